"""What a lens model costs a frame: ``Simulator.render()`` (Blender's colour through the Cycles
custom camera, and the ground truth cast through the lens) against the plain pinhole, side by
side on the same frames of a real medium site.

Builds (or reuses from ``--cache``) the medium site of ``--seed``, plans the batch job's orbit
and renders ``--frames`` of its poses at 640x480 with the ``preview`` preset, taking turns:
pinhole, opencv (``--opencv``), fisheye (``--fisheye``), the order rotated every round.
Switching lens re-synchronises Cycles, so each block starts with one untimed render. Reports
the median seconds a frame of each, and the ratio to the pinhole.

Usage: .venv/bin/python benchmarks/lens.py [--frames 0 13 26] [--rounds 3] [--seed 0]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.blender import session  # noqa: E402,F401  (bpy first)



def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--opencv", default="-0.22,0.05,0.0015,-0.001")
    ap.add_argument("--fisheye", default="0.02,-0.01,0.003,-0.0005")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from render import preview_frames

    args, sim, poses = preview_frames(ap)
    lenses = {"pinhole": (), "opencv": tuple(map(float, args.opencv.split(","))),
              "fisheye": tuple(map(float, args.fisheye.split(",")))}
    times = {name: [] for name in lenses}
    names = list(lenses)
    for r in range(args.rounds):
        for name in names[r % len(names):] + names[:r % len(names)]:
            sim.set_lens(name, lenses[name])
            sim.set_world_from_camera(poses[args.frames[0]], check_collisions=False)
            sim.render()  # untimed: Cycles re-synchronises after the camera changed type
            for f in args.frames:
                sim.set_world_from_camera(poses[f], check_collisions=False)
                t0 = time.perf_counter()
                sim.render()
                times[name].append(time.perf_counter() - t0)
    base = statistics.median(times["pinhole"])
    print(f"medium seed {args.seed}, 640x480 preview, frames {args.frames}, {args.rounds} rounds")
    for name in names:
        t = statistics.median(times[name])
        print(f"{name:8} {t:7.3f} s a frame   {t / base:5.3f}x the pinhole")


if __name__ == "__main__":
    main()
