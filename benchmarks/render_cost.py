"""Seconds per frame of the preview preset on a medium site, for several checkouts side by
side (issue #38's render-cost target: at most 1.3x the code before its textures).

Each checkout builds medium seed 0 (once, into --work) and renders five fixed views at
640x480 with `Simulator.render` in a process of its own (importing that checkout's code),
the first view dropped as a warm-up; the checkouts take turns for --rounds rounds, so that
the machine's drift falls on all of them alike. Fixed views, not respawned ones: a site's
spawn points move when its layout does, and one view can cost twice another.

Usage: .venv/bin/python benchmarks/render_cost.py CHECKOUT [CHECKOUT ...] [--rounds 2] [--work DIR]
(a CHECKOUT is a folder holding a checkout of this project, e.g. a `git worktree`; the first
is the reference of the ratios).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

VIEWS = [((-25, -30, 12), (0, 0, 0)), ((20, -25, 8), (0, 5, 2)), ((0, 30, 15), (0, 0, 0)),
         ((-30, 10, 6), (10, 0, 2)), ((10, 10, 20), (-10, -10, 0))]  # (eye, target), metres

CHILD = """
import json, os, sys, time
import numpy as np
root, out, views = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
sys.path.insert(0, root)
os.chdir(root)
from generator import Simulator
from generator.geometry.camera import look_at
from generator.scene import build_site
if not os.path.exists(os.path.join(out, "site.blend")):
    build_site(0, "medium", out, preview=False)
sim = Simulator(os.path.join(out, "site.blend"), points_density=0.01, seed=0, render_preset="preview")
sim.configure_render(resolution=(640, 480))
times = []
for eye, target in views:
    sim.set_world_from_camera(look_at(np.array(eye, float), np.array(target, float)), check_collisions=False)
    t = time.perf_counter()
    sim.render()
    times.append(time.perf_counter() - t)
print("RESULT " + json.dumps(times))
"""


def seconds_per_frame(checkout: Path, work: Path) -> float:
    """Mean seconds of the views after the first, in a fresh process of ``checkout``."""
    out = work / checkout.resolve().as_posix().strip("/").replace("/", "_")
    run = subprocess.run([sys.executable, "-c", CHILD, str(checkout.resolve()), str(out), json.dumps(VIEWS)],
                         capture_output=True, text=True)
    line = next((x for x in run.stdout.splitlines() if x.startswith("RESULT ")), None)
    if run.returncode != 0 or line is None:
        raise SystemExit(f"render_cost: {checkout} failed: {run.stderr.strip().splitlines()[-1:]}")
    times = json.loads(line[len("RESULT "):])
    return sum(times[1:]) / len(times[1:])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("checkouts", nargs="+", type=Path)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--work", type=Path, default=None, help="where the sites are built (default: a temporary folder)")
    args = p.parse_args()
    for c in args.checkouts:
        if not (c / "generator" / "__init__.py").is_file():
            p.error(f"{c} is not a checkout of this project (no generator/__init__.py); pass a git worktree's folder")
    if args.rounds < 1:
        p.error("--rounds must be at least 1")
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        rows = {c: [] for c in args.checkouts}
        for _ in range(args.rounds):
            for c in args.checkouts:
                rows[c].append(seconds_per_frame(c, work))
    first = rows[args.checkouts[0]]
    print(f"{'checkout':40s} {'s/frame per round':30s} ratio to the first, per round")
    for c, values in rows.items():
        ratios = " ".join(f"{v / f:.2f}x" for v, f in zip(values, first))
        print(f"{str(c):40s} {' '.join(f'{v:.2f}' for v in values):30s} {ratios}")


if __name__ == "__main__":
    main()
