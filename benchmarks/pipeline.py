"""Where a frame's time goes in the batch job's loop (issue #42): the wall time of the whole
loop, the time inside Cycles' path tracing, and the CPU time of everything else by stage.

Builds (or reuses from ``--cache``) the site of ``--seed`` and ``--preset``, plans the batch
job's orbit and flies its first ``--frames`` frames through the real trajectory loop
(generator/batch/fly.py ``fly``: every default output and export, written into a temporary
folder) at ``--resolution`` with the ``preview`` render preset on ``--device``. Measured per
frame, with the loop's code untouched (its functions wrapped by this script):

- ``wall_s_per_frame``: the loop's wall time (set-up of the sinks and their closing included)
  as the batch job runs it on this device; ``wall_s_per_frame_sinks_in_the_loop``: the sinks
  called between renders (the CPU's way; the first run, whose stages are the ones reported);
  ``wall_s_per_frame_sinks_threaded``: the sinks writing in a thread of their own beside the
  renderer (a GPU's way: generator/batch/overlap.py);
- ``cycles_s_per_frame``: Cycles' path tracing, from Blender's ``render_stats`` messages: the
  wall time from a frame's first ``Sample`` message to its last (scene synchronisation,
  denoising, the compositor and Blender's own file output are outside it);
- ``outside_cycles_cpu_s_per_frame``: the process's CPU time (every thread) less the CPU time
  spent during path tracing;
- ``stages``: CPU and wall seconds per frame of each stage: ``blender_render`` (the render
  call outside path tracing: Blender's sync, denoising, the compositor, its EXR/TIFF output
  and our reading of it, the pixel-centre cast that runs beside it, labels), ``geometry_modalities`` (normals, flow: the
  rest of ``render_outputs``), ``cycles_path_tracing`` (the render call's path tracing, apart
  from ``blender_render``), ``point_visibility`` (``compute_point_cloud``, twice a frame),
  and each sink's ``add_frame`` and ``close`` (frames: EXR and PNG writing; coco, tracks,
  colmap, nerfstudio, previews...; a sink's ``close`` spread over the frames), ``other`` the
  rest of the loop.

Usage: .venv/bin/python benchmarks/pipeline.py [--frames 10] [--seed 0] [--preset medium]
       [--resolution 640x480] [--device cpu] [--json FILE] [--cache /tmp/buildee-render-bench]
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.blender import session  # noqa: E402

bpy = session.bpy
import numpy as np  # noqa: E402

from generator import Simulator  # noqa: E402

SAMPLE = re.compile(r"Sample \d+/\d+")


class Clock:
    """CPU (all threads) and wall seconds spent in named stages."""

    def __init__(self):
        self.cpu, self.wall = defaultdict(float), defaultdict(float)

    def wrap(self, owner, attr: str, name: str) -> None:
        """Time every call of ``owner.attr`` as stage ``name`` (an instance's or a class's)."""
        original = getattr(owner, attr)

        def timed(*args, **kwargs):
            c0, w0 = time.process_time(), time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                self.cpu[name] += time.process_time() - c0
                self.wall[name] += time.perf_counter() - w0

        setattr(owner, attr, timed)

    def snapshot(self) -> tuple[dict, dict]:
        """(CPU, wall) seconds by stage so far (copies)."""
        return dict(self.cpu), dict(self.wall)


class PathTracing:
    """Cycles' path tracing per render, from ``render_stats``: from the first ``Sample``
    message to the last, wall and process CPU seconds."""

    def __init__(self):
        self.wall = self.cpu = 0.0
        self.first = None
        self.last = None
        bpy.app.handlers.render_stats.append(self.stats)
        bpy.app.handlers.render_post.append(self.done)

    def stats(self, text, *_):
        if SAMPLE.search(str(text)):
            now = (time.perf_counter(), time.process_time())
            self.first = self.first or now
            self.last = now

    def done(self, *_):
        if self.first is not None:
            self.wall += self.last[0] - self.first[0]
            self.cpu += self.last[1] - self.first[1]
        self.first = self.last = None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--preset", default="medium")
    ap.add_argument("--resolution", default="640x480")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/buildee-render-bench"))
    args = ap.parse_args()
    sim, traj = flight(args)
    clock, tracing = instrument(sim)
    cpu, wall = fly_once(sim, traj, args.seed, overlap=False)  # the stages, each in the loop's thread
    stages, cycles = clock.snapshot(), (tracing.wall, tracing.cpu)
    _, wall_overlapped = fly_once(sim, traj, args.seed, overlap=True)  # the way on a GPU
    result = summary(args, sim, len(traj), (cpu, wall, wall_overlapped), cycles, stages)
    print(f"{result['site']}, {result['frames']} frames at {args.resolution}, preview, {result['device']}")
    for key in ("wall_s_per_frame", "wall_s_per_frame_sinks_in_the_loop", "wall_s_per_frame_sinks_threaded",
                "cycles_s_per_frame",
                "cycles_cpu_s_per_frame", "outside_cycles_cpu_s_per_frame"):
        print(f"  {key:36} {result[key]:8.3f}")
    print(f"  {'stage':36} {'cpu s/frame':>12} {'wall s/frame':>12}")
    for k, v in result["stages"].items():
        print(f"  {k:36} {v['cpu_s_per_frame']:12.3f} {v['wall_s_per_frame']:12.3f}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))


def flight(args):
    """A Simulator of the site at the resolution, and the first ``--frames`` of its orbit
    (one untimed render done: the first compiles and synchronises)."""
    from generator.batch.config import plan_trajectory
    from generator.scene import build_site
    from trajectories import Trajectory

    folder = args.cache / f"site-{args.preset}-{args.seed}"
    if not (folder / "site.blend").exists():
        build_site(args.seed, args.preset, folder, preview=False, frames=250)
    sim = Simulator(folder / "site.blend", points_density=2.0, seed=args.seed, render_preset="preview")
    width, height = (int(v) for v in args.resolution.split("x"))
    sim.configure_render(resolution=(width, height), device=args.device)
    start = sim.respawn_camera()
    orbit = plan_trajectory("orbit", sim, sim.spawn_points, start, args.seed, 40, 10.0)
    traj = Trajectory(orbit.poses[:args.frames], orbit.timestamps[:args.frames], orbit.kind, [], dict(orbit.params))
    sim.set_frame(1)
    sim.set_world_from_camera(traj.poses[0], check_collisions=False)
    sim.render()
    return sim, traj


def instrument(sim) -> tuple[Clock, PathTracing]:
    """The loop's stages wrapped in a :class:`Clock`, Cycles' path tracing followed."""
    from exporters.sinks import load_sinks

    clock, tracing = Clock(), PathTracing()
    clock.wrap(sim, "render", "blender_render")
    clock.wrap(sim, "render_outputs", "render_outputs")
    clock.wrap(sim, "compute_point_cloud", "point_visibility")
    for name, sink in load_sinks().items():
        clock.wrap(sink, "add_frame", f"sink_{name}_add_frame")
        clock.wrap(sink, "close", f"sink_{name}_close")
    return clock, tracing


def fly_once(sim, traj, seed: int, overlap: bool) -> tuple[float, float]:
    """(process CPU, wall) seconds of the trajectory loop writing into a temporary folder."""
    from generator.batch.fly import fly

    with tempfile.TemporaryDirectory(prefix="buildee-pipeline-") as tmp:
        c0, w0 = time.process_time(), time.perf_counter()
        fly(sim, traj, Path(tmp) / "orbit", seed, overlap=overlap)
        return time.process_time() - c0, time.perf_counter() - w0


def summary(args, sim, n: int, times, cycles, stages) -> dict:
    """The JSON document: per-frame figures and the stages (CPU, wall) of the serial run."""
    cpu, wall, wall_overlapped = times
    tracing_wall, tracing_cpu = cycles
    stage_cpu, stage_wall = stages
    stage_cpu["geometry_modalities"] = stage_cpu.pop("render_outputs") - stage_cpu["blender_render"]
    stage_wall["geometry_modalities"] = stage_wall.pop("render_outputs") - stage_wall["blender_render"]
    stage_cpu["blender_render"] -= tracing_cpu  # the render call outside Cycles' path tracing
    stage_wall["blender_render"] -= tracing_wall
    stage_cpu["cycles_path_tracing"], stage_wall["cycles_path_tracing"] = tracing_cpu, tracing_wall
    stage_cpu["other"] = cpu - sum(stage_cpu.values())
    stage_wall["other"] = wall - sum(stage_wall.values())
    width, height = (int(v) for v in args.resolution.split("x"))
    return {"device": f"{sim.render_device} ({args.device}); {_machine()}", "frames": n,
            "resolution": [width, height], "site": f"{args.preset} seed {args.seed}",
            "wall_s_per_frame": (wall_overlapped if sim.render_device != "CPU" else wall) / n,
            "wall_s_per_frame_sinks_in_the_loop": wall / n, "wall_s_per_frame_sinks_threaded": wall_overlapped / n,
            "cycles_s_per_frame": tracing_wall / n, "cycles_cpu_s_per_frame": tracing_cpu / n,
            "outside_cycles_cpu_s_per_frame": (cpu - tracing_cpu) / n, "cpu_s_per_frame": cpu / n,
            "stages": {k: {"cpu_s_per_frame": stage_cpu[k] / n, "wall_s_per_frame": stage_wall[k] / n}
                       for k in sorted(stage_cpu, key=lambda k: -stage_cpu[k])}}


def _machine() -> str:
    import os

    return f"{os.cpu_count()} CPU cores"


if __name__ == "__main__":
    main()
