"""``python -m generator.scene --seed 0 --preset medium --out DIR``: build and save one site;
``--survey 0-99 --out DIR``: a diversity report of many seeds' plans (generator/scene/survey.py)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from ..batch.config import MAX_FRAMES
from ..checks import MAX_SEED
from ..cli_args import OneLineParser, check_out_folder, int_at_least, out_folder
from .building_types import all_types
from .catalogue.ground import SURFACES
from .contexts import CONTEXTS
from .site import LAYOUTS, PRESETS
from .timeline import MAX_STAGES
from .weather import SEASONS, WEATHERS


def main(argv=None) -> int:
    p = OneLineParser(prog="python -m generator.scene", description="Build one procedural construction site and save it.")
    p.add_argument("--seed", type=int_at_least(0, "seed", MAX_SEED),
                   help="site seed, an integer from 0 to 2**63-1 (required unless --survey)")
    p.add_argument("--survey", metavar="A-B", help="plan seeds A to B (nothing rendered) and write a diversity report, "
                   "survey.json and survey.md, into --out (docs/scenes.md, 'Survey')")
    p.add_argument("--preset", default="medium", choices=sorted(PRESETS), help="site preset (default: medium)")
    p.add_argument("--out", type=out_folder, default=Path("site"), help="output folder (default: ./site)")
    p.add_argument("--size", type=float, help="site side in metres, up to 1000 and at least small 42, medium 51, large 53 (default: the preset's)")
    p.add_argument("--density", type=float, help="object density multiplier, 1 = typical (default: the preset's)")
    p.add_argument("--layout", choices=LAYOUTS, help="arrangement of the props (default: scattered)")
    p.add_argument("--phase", type=float, help="share of the planned floors built, 0 to 1 (default: random per building)")
    p.add_argument("--frames", type=int_at_least(2, "frames", MAX_FRAMES),
                   help=f"animation length in frames at 10 fps, 2 to {MAX_FRAMES} (default: 250)")
    p.add_argument("--stages", type=int_at_least(1, "stages", MAX_STAGES), default=1,
                   help=f"stages of the site's timeline, 1 to {MAX_STAGES} (default: 1; docs/phases.md)")
    p.add_argument("--stage", type=int_at_least(0, "stage", MAX_STAGES - 1), default=0,
                   help="which stage of the timeline to build, 0 to stages-1 (default: 0)")
    p.add_argument("--weather", choices=WEATHERS, help="sky and weather (default: drawn per seed; docs/scenes.md)")
    p.add_argument("--ground", choices=SURFACES, help="the ground's surface (default: drawn per seed; docs/scenes.md)")
    p.add_argument("--building-type", choices=[t.name for t in all_types()],
                   help="the type of every building (default: drawn per building; docs/scenes.md)")
    p.add_argument("--context", choices=list(CONTEXTS), help="what surrounds the site (default: drawn per seed; docs/scenes.md)")
    p.add_argument("--season", choices=list(SEASONS), help="the season; snow: a winter with snow lying (default: drawn per seed; "
                                                         "docs/scenes.md)")
    p.add_argument("--no-preview", action="store_true", help="skip the preview render")
    p.add_argument("--previews", action="store_true",
                   help="with --survey: also build every seed and keep its preview, its colour and a contact sheet "
                        "(about 17 s a medium seed)")
    args = p.parse_args(argv)
    check_out_folder(p, args.out)
    if args.seed is None and args.survey is None:
        p.error("give --seed N (one site) or --survey A-B (a report of many)")
    if args.previews and args.survey is None:
        p.error("--previews goes with --survey A-B (one site always has its preview)")
    if args.stage >= args.stages:
        p.error(f"--stage {args.stage} is outside the timeline's stages 0 to {args.stages - 1}")
    overrides = {k: getattr(args, k) for k in ("size", "density", "layout", "phase", "frames", "weather", "ground", "building_type", "context", "season") if getattr(args, k) is not None}
    from . import build_site

    from exporters.write_guard import WriteRefused, claim_folder

    try:  # a new or empty folder, or one holding only this tool's earlier outputs, unchanged
        claimed = claim_folder(args.out, "--out", "python -m generator.scene")
    except WriteRefused as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.survey is not None:
        return _survey(p, args, overrides, claimed)
    t0 = time.perf_counter()
    try:
        result = build_site(args.seed, args.preset, args.out, preview=not args.no_preview, stage=args.stage,
                            stages=args.stages, **overrides)
    except (ValueError, TypeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"error: cannot write to {args.out}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    claimed.seal()
    info = result.info
    print(f"seed {args.seed} ({args.preset}): {info['objects']} objects, {info['triangles']:,} triangles, "
          f"built in {time.perf_counter() - t0:.1f} s -> {result.blend}")
    return 0


def _survey(p, args, overrides: dict, claimed) -> int:
    """``--survey``: plan the seeds, write the report, print the totals' headline."""
    from tqdm import tqdm

    from .survey import parse_seeds, write_survey

    try:
        seeds = parse_seeds(args.survey)
        total = write_survey(seeds, args.out, args.preset, lambda s: tqdm(s, unit="seed", file=sys.stderr),
                             previews=args.previews, **overrides)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    claimed.seal()
    print(f"{total['seeds']} seeds ({args.preset}): {len(total['kinds'])} asset kinds, "
          f"{len(total['surface'])} ground surfaces, {len(total['weather'])} weathers -> {args.out / 'survey.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
