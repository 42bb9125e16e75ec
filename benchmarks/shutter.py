"""What motion blur and a rolling shutter cost a frame: ``Simulator.render_outputs(["rgb"],
poses, ...)`` with the shutter closed against open (``--shutter`` seconds, the camera moving
along the orbit and the machines along their animation during the exposure) and against a
rolling shutter (``--readout`` seconds: Cycles' rows at their times, and the ground truth the
render keeps cast row by row), side by side on the same frames of a real medium site.

Builds (or reuses from ``--cache``) the medium site of ``--seed``, plans the batch job's orbit
and renders ``--frames`` of its poses at 640x480 with the ``preview`` preset, the two shutters
taking turns, the order swapped every round; switching the shutter re-synchronises Cycles, so
each block starts with one untimed render. Reports the median seconds a frame of each.

Usage: .venv/bin/python benchmarks/shutter.py [--shutter 0.05] [--readout 0.03] [--frames 0 13 26] [--rounds 3]
       [--seed 0]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.blender import session  # noqa: E402,F401  (bpy first)
import numpy as np  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shutter", type=float, default=0.05)
    ap.add_argument("--readout", type=float, default=0.03)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from render import preview_frames

    args, sim, poses = preview_frames(ap)
    matrices = []
    for i in range(len(poses)):
        sim.set_frame(1 + i)
        matrices.append(sim.dynamic_object_matrices())
    matrices = np.stack(matrices)
    shutters = {"closed": (0.0, 0.0), f"{args.shutter:g} s": (args.shutter, 0.0),
                f"rolling {args.readout:g} s": (0.0, args.readout)}
    times = {name: [] for name in shutters}
    names = list(shutters)
    for r in range(args.rounds):
        for name in names if r % 2 == 0 else names[::-1]:
            sim.set_shutter(*shutters[name])
            for k, f in enumerate([args.frames[0]] + list(args.frames)):
                sim.set_frame(1 + f)
                sim.set_world_from_camera(poses[f], check_collisions=False)
                t0 = time.perf_counter()
                sim.render_outputs(["rgb"], poses, matrices, f)
                if k:  # the first is untimed: Cycles re-synchronises after the shutter changed
                    times[name].append(time.perf_counter() - t0)
    base = statistics.median(times["closed"])
    print(f"medium seed {args.seed}, 640x480 preview, frames {args.frames}, {args.rounds} rounds")
    for name in names:
        t = statistics.median(times[name])
        print(f"shutter {name:16} {t:7.3f} s a frame   {t / base:5.3f}x closed")


if __name__ == "__main__":
    main()
