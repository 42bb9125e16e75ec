"""Per-frame cost of the object annotations (the ``coco`` and ``boxes3d`` sinks) on a real
medium site at 640x480, side by side with the preview render of the same frames.

Builds the medium site of ``--seed`` (cached under ``--cache``), plans the batch job's orbit
(40 frames) and, for ``--frames`` of its poses: one ``Simulator.render()`` with the preview
preset (the reference: what the frame costs to render), then the two sinks' ``add_frame`` on
that render's instance map, and their ``close`` at the end (JSON writing). Reports the median
seconds per frame of each and their ratio to the render; the sinks' cost includes the RLE
encoding, tight boxes, the exact amodal boxes of every instance in view and the 3D boxes.

Usage: .venv/bin/python benchmarks/annotations.py [--seed 0] [--frames 0 13 26] [--cache /tmp/buildee-bench]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.blender import session  # noqa: E402,F401  (bpy before open3d)
import numpy as np  # noqa: E402

from generator import Simulator  # noqa: E402
from render import medium_site  # noqa: E402  (benchmarks/render.py: the same cached medium site)

RESOLUTION = (640, 480)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--frames", type=int, nargs="+", default=[0, 13, 26])
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "buildee-bench")
    args = ap.parse_args()

    from exporters.boxes3d import Boxes3DWriter
    from exporters.coco import CocoWriter
    from exporters.sinks import FrameRecord, TrajectoryContext
    from generator.batch.config import plan_trajectory

    sim = Simulator(medium_site(args.seed, args.cache), points_density=2.0, seed=args.seed, render_preset="preview")
    sim.configure_render(resolution=RESOLUTION)
    traj = plan_trajectory("orbit", sim, sim.spawn_points, sim.respawn_camera(), args.seed, 40, 10.0)
    with tempfile.TemporaryDirectory() as tmp:
        ctx = TrajectoryContext(Path(tmp), "orbit", args.seed, sim.K.copy(), sim.width, sim.height, traj.poses,
                                traj.timestamps, list(sim.labels), sim.instance_table, sim.scene_parts(),
                                sim.dynamic_objects, sim.point_table(), ("rgb", "depth", "label", "instance"),
                                clip=(float(sim.clip_start), float(sim.clip_end)))
        t0 = time.perf_counter()
        sinks = {"coco": CocoWriter(ctx), "boxes3d": Boxes3DWriter(ctx)}
        setup = time.perf_counter() - t0
        render_s, sink_s, instances = [], {k: [] for k in sinks}, []
        for i in args.frames:
            sim.set_frame(1 + i)
            sim.set_world_from_camera(traj.poses[i], check_collisions=False)
            sim.render()  # untimed: settings and scene synchronisation
            t0 = time.perf_counter()
            r = sim.render()
            render_s.append(time.perf_counter() - t0)
            record = FrameRecord(i, float(traj.timestamps[i]), traj.poses[i], {"instance": r.instance}, sim.point_positions,
                                 np.zeros(sim.num_points, bool), sim.dynamic_object_matrices(), 0.0)
            instances.append(int(len(np.unique(r.instance[r.instance >= 0]))))
            for name, sink in sinks.items():
                t0 = time.perf_counter()
                sink.add_frame(record)
                sink_s[name].append(time.perf_counter() - t0)
        close = {}
        for name, sink in sinks.items():
            t0 = time.perf_counter()
            sink.close()
            close[name] = time.perf_counter() - t0
    render = float(np.median(render_s))
    result = {"seed": args.seed, "frames": args.frames, "resolution": RESOLUTION, "instances_in_view": instances,
              "parts": len(sim.object_names), "render_preview_s": render, "sink_setup_s": setup}
    for name in sinks:
        med = float(np.median(sink_s[name]))
        result[name] = {"add_frame_s": med, "share_of_render": med / render, "close_s_for_these_frames": close[name]}
    result["together_share_of_render"] = sum(result[n]["add_frame_s"] for n in sinks) / render
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
