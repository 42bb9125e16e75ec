"""How much a seed's look varies from seed to seed, for several checkouts side by side
(issue #39's target: the spread of the previews' mean colour at least 2x the code before it).

Each checkout builds the medium sites of --seeds in a process of its own (importing that
checkout's code: `build_site` with its preview, 480x320 from the scene camera, the preview
render preset) and this script measures every preview the same way
(generator/scene/survey_previews.py of this checkout): the mean of each channel of its 8-bit
sRGB pixels, and over the seeds the standard deviation of each channel's mean (the colour
spread) and their mean. The first checkout is the reference of the ratios.

Usage: .venv/bin/python benchmarks/diversity.py CHECKOUT [CHECKOUT ...] [--seeds 0-23] [--work DIR] [--json FILE]
(a CHECKOUT is a folder holding a checkout of this project, e.g. a `git worktree`).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.scene.survey import parse_seeds  # noqa: E402
from generator.scene.survey_previews import colour_spread, preview_colour  # noqa: E402

CHILD = """
import os, sys
root, out, seeds = sys.argv[1], sys.argv[2], [int(s) for s in sys.argv[3].split(",")]
sys.path.insert(0, root)
os.chdir(root)
from generator.scene import build_site
for seed in seeds:
    build_site(seed, "medium", os.path.join(out, str(seed)), preview=True)
    print("BUILT", seed, flush=True)
"""


def previews(checkout: Path, seeds: list[int], work: Path) -> list[Path]:
    """Build the seeds with ``checkout``'s code; the paths of their previews, in order."""
    out = work / checkout.resolve().as_posix().strip("/").replace("/", "_")
    run = subprocess.run([sys.executable, "-c", CHILD, str(checkout.resolve()), str(out), ",".join(map(str, seeds))],
                         capture_output=True, text=True)
    if run.returncode != 0:
        raise SystemExit(f"diversity: {checkout} failed: {run.stderr.strip().splitlines()[-1:]}")
    return [out / str(s) / "preview.png" for s in seeds]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("checkouts", nargs="+", type=Path)
    ap.add_argument("--seeds", default="0-23", help="a seed or a range A-B (default: 0-23)")
    ap.add_argument("--work", type=Path, help="where the sites are built (default: a temporary folder)")
    ap.add_argument("--json", type=Path, help="write the figures to this JSON file")
    args = ap.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for c in args.checkouts:
        if not (c / "generator" / "scene").is_dir():
            print(f"error: {c} is not a checkout of this project (no generator/scene)", file=sys.stderr)
            return 2
    with tempfile.TemporaryDirectory(prefix="diversity-") as scratch:
        work = args.work or Path(scratch)
        figures = {}
        for c in args.checkouts:
            means = [preview_colour(p) for p in previews(c, seeds, work)]
            figures[str(c)] = {"means": means, "spread": colour_spread(means)}
    ref = figures[str(args.checkouts[0])]["spread"]["mean"]
    print(f"{'checkout':<40}{'R':>8}{'G':>8}{'B':>8}{'mean':>8}{'ratio':>7}")
    for name, f in figures.items():
        s = f["spread"]
        print(f"{name:<40}{s['r']:>8.4f}{s['g']:>8.4f}{s['b']:>8.4f}{s['mean']:>8.4f}{s['mean'] / ref:>7.2f}")
    if args.json:
        args.json.write_text(json.dumps({"seeds": seeds, "checkouts": figures}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
