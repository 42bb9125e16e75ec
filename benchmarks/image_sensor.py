"""What the image sensor costs a frame, beside the render it follows: ``Simulator.render()``
of real medium-site frames with the ideal sensor, and the time each sensor option
(generator/image_sensor.py ``ImageSensor.apply``, what ``render()`` adds) takes on those same
rendered images, in the same run.

Builds (or reuses from ``--cache``) the medium site of ``--seed``, plans the batch job's orbit
and renders ``--frames`` of its poses at 640x480 with the ``preview`` preset, ``--rounds``
times; after each render, every sensor option processes its display image (the order rotated
every round). Reports the median seconds a frame of the render and of each option, and the
option's share of the frame. (Timing whole renders with and without a sensor measures the
render's own 10% variation, not the sensor.)

Usage: .venv/bin/python benchmarks/image_sensor.py [--frames 0 13 26] [--rounds 3] [--seed 0]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.blender import session  # noqa: E402,F401  (bpy first)


SENSORS = {  # name: set_image_sensor's arguments (the ideal sensor's render() does nothing more)
    "exposure +1": {"exposure": 1.0},
    "auto exposure": {"exposure": "auto"},
    "noise 6000,3": {"full_well_e": 6000.0, "read_noise_e": 3.0},
    "auto + noise + jpeg 90": {"exposure": "auto", "full_well_e": 6000.0, "read_noise_e": 3.0, "jpeg_quality": 90},
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from render import preview_frames

    args, sim, poses = preview_frames(ap)
    from generator.image_sensor import view_stream

    sim.set_world_from_camera(poses[args.frames[0]], check_collisions=False)
    sim.render()  # untimed: Cycles' first synchronisation
    sensors = {name: sim.set_image_sensor(**kw) for name, kw in SENSORS.items()}
    sim.set_image_sensor()
    times = {name: [] for name in ["render"] + list(SENSORS)}
    names = list(SENSORS)
    for r in range(args.rounds):
        for f in args.frames:
            sim.set_world_from_camera(poses[f], check_collisions=False)
            t0 = time.perf_counter()
            out = sim.render()
            times["render"].append(time.perf_counter() - t0)
            for name in names[r % len(names):] + names[:r % len(names)]:
                t0 = time.perf_counter()
                sensors[name].apply(out.rgb, view_stream(sim.seed, out.frame, out.world_from_camera))
                times[name].append(time.perf_counter() - t0)
    base = statistics.median(times["render"])
    print(f"medium seed {args.seed}, 640x480 preview, frames {args.frames}, {args.rounds} rounds")
    print(f"{'render (ideal sensor)':24} {base:7.3f} s a frame")
    for name in names:
        t = statistics.median(times[name])
        print(f"{name:24} {t:7.3f} s a frame   +{100 * t / base:4.1f}% of the frame")


if __name__ == "__main__":
    main()
