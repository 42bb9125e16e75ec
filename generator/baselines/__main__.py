"""``python -m generator.baselines exploration|reconstruction``: the paper's tables 2 and 3.

  python -m generator.baselines exploration --seeds 0 137 281 --steps 500 --runs 10 --out DIR
  python -m generator.baselines reconstruction --seed 0 --steps 100 --voxel 0.05 --out DIR
"""

from __future__ import annotations

import argparse
import sys
import time

from ..checks import MAX_SEED
from ..cli_args import (OneLineParser, check_out_folder, first_repeated, int_at_least, out_folder, positive_float,
                        resolution)


def parse_args(argv=None) -> argparse.Namespace:
    from ..scene import PRESETS

    p = OneLineParser(prog="python -m generator.baselines", description="The paper's baselines and their tables.")
    sub = p.add_subparsers(dest="task", required=True, parser_class=OneLineParser)
    e = sub.add_parser("exploration", help="table 2 / figure 8: random walks, coverage AUC (geometry only)")
    e.add_argument("--seeds", type=int_at_least(0, "seed", MAX_SEED), nargs="+", default=[0, 137, 281])
    e.add_argument("--steps", type=int_at_least(1, "steps"), default=500, help="actions per run (default 500)")
    e.add_argument("--runs", type=int_at_least(1, "runs"), default=10, help="runs per seed and method (default 10)")
    e.add_argument("--max-depth", type=positive_float("a positive number of metres"), default=20.0, help="points count as seen within this depth (default 20 m)")
    e.add_argument("--points-density", type=positive_float(), default=5.0, help="surface points per square metre (default 5, as the paper's evaluation code)")
    e.add_argument("--scene-preset", choices=sorted(PRESETS), default="medium")
    e.add_argument("--paper-code-actions", action="store_true",
                   help="random walk with the paper's code's actions as written (two lefts, no right)")
    e.add_argument("--out", type=out_folder, required=True)
    r = sub.add_parser("reconstruction", help="table 3 / figure 9: random walk, depth + labels fused into voxels")
    r.add_argument("--seed", type=int_at_least(0, "seed", MAX_SEED), default=0)
    r.add_argument("--steps", type=int_at_least(1, "steps"), default=100, help="actions (default 100), one frame rendered before each")
    r.add_argument("--voxel", type=positive_float("a positive number of metres"), default=0.05, help="voxel size in metres (default 0.05)")
    r.add_argument("--tau", type=positive_float("a positive number of metres"), default=0.1, help="distance threshold of the metrics (default 0.1 m)")
    r.add_argument("--gt-density", type=positive_float("a positive number of points per square metre"), default=100.0,
                   help="points per square metre of the ground-truth cloud (default 100, as the paper's code)")
    r.add_argument("--resolution", type=resolution, default=(640, 480), help="WxH pixels (default 640x480)")
    r.add_argument("--scene-preset", choices=sorted(PRESETS), default="medium")
    r.add_argument("--out", type=out_folder, required=True)
    args = p.parse_args(argv)
    if args.task == "exploration" and first_repeated(args.seeds) is not None:
        p.error(f"--seeds lists seed {first_repeated(args.seeds)} twice")
    check_out_folder(p, args.out)
    from ..batch.config import MAX_SCORING_POINTS, site_area_lower_bound

    area = site_area_lower_bound(args.scene_preset)
    flag, density = ("--gt-density", args.gt_density) if args.task == "reconstruction" else ("--points-density",
                                                                                           args.points_density)
    if density * area > MAX_SCORING_POINTS:
        p.error(f"{flag} {density:g}: a {args.scene_preset} site has more than {area:,.0f} m^2 of "
                f"surface, so over {density * area:,.0f} points; the limit is {MAX_SCORING_POINTS:,}")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    from exporters.write_guard import WriteRefused, claim_folder

    try:  # a new or empty folder, or one holding only this tool's earlier outputs, unchanged
        claimed = claim_folder(args.out, "--out", "python -m generator.baselines")
    except WriteRefused as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    from ..blender import session

    session.set_log_path(args.out / "blender.log")
    t0 = time.perf_counter()
    try:
        if args.task == "exploration":
            from .exploration import run_exploration, table

            results = run_exploration(args.seeds, args.steps, args.runs, args.out, args.scene_preset, args.max_depth,
                                      args.points_density, paper_code_actions=args.paper_code_actions)
            print(table(results))
            print(f"modified random walk beats random walk on every seed: {results['modified_beats_random_on_every_seed']}")
        else:
            from .reconstruction import run_reconstruction, table

            results = run_reconstruction(args.seed, args.steps, args.voxel, args.out, args.scene_preset,
                                         args.resolution, args.tau, (args.gt_density,))
            print(table(results))
    except ValueError as exc:  # the Simulator's and the site's own checks (one line each), e.g. a density too high
        print(f"error: {str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__}", file=sys.stderr)
        return 2
    claimed.seal()
    print(f"took {time.perf_counter() - t0:.0f} s; results in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
