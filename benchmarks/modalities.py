"""Per-frame cost of the geometry modalities (normal, flow, backward_flow) beside the preview
render of the same frame, on a generated site.

    .venv/bin/python benchmarks/modalities.py [--seed 0] [--preset medium] [--frames 4] [--resolution 640x480]

For each frame of an orbit (the batch job's first trajectory): the Blender render with the
``preview`` preset (``sim.render()``, what every frame costs already), then the new
modalities alone (``sim.render_outputs(("normal", "flow", "backward_flow"), ...)``: one ray
per pixel centre and the flow of every hit point to both neighbouring frames), then the extra
EXR bytes written for them (``write_frame`` of the frame with and without them). Reports
medians in seconds and the new modalities' share of the render time. The site is built into
a temporary folder (not timed).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

NEW = ("normal", "flow", "backward_flow")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--preset", default="medium")
    p.add_argument("--frames", type=int, default=4)
    p.add_argument("--resolution", default="640x480")
    args = p.parse_args()
    w, h = (int(v) for v in args.resolution.split("x"))

    from generator import Simulator
    from generator.batch.config import plan_trajectory
    from generator.batch.fly import object_matrices_over
    from generator.scene import build_site
    from exporters.exr import write_frame

    tmp = Path(tempfile.mkdtemp(prefix="bench-modalities-"))
    site = build_site(args.seed, args.preset, tmp / "scene", frames=250)
    sim = Simulator(site.blend, points_density=2.0, seed=args.seed, max_pcl_depth=60.0, render_preset="preview")
    sim.configure_render(resolution=(w, h), device="cpu")
    traj = plan_trajectory("orbit", sim, sim.spawn_points, sim.respawn_camera(), args.seed, 40, 10.0)
    matrices = object_matrices_over(sim, len(traj))
    rows = []
    for i in np.linspace(1, len(traj) - 2, args.frames).round().astype(int):
        sim.set_frame(1 + i)
        sim.set_world_from_camera(traj.poses[i], check_collisions=False)
        t0 = time.perf_counter()
        base = sim.render()
        t1 = time.perf_counter()
        new = sim.render_outputs(NEW, traj.poses, matrices, int(i))
        t2 = time.perf_counter()
        old_outputs = {k: base.outputs[k] for k in ("rgb_linear", "depth", "label", "instance")}
        t3 = time.perf_counter()
        write_frame(tmp / "old.exr", old_outputs)
        t4 = time.perf_counter()
        write_frame(tmp / "new.exr", old_outputs | {k: new[k] for k in NEW})
        t5 = time.perf_counter()
        hit = np.isfinite(new["flow"]).all(-1)
        rows.append({"render": t1 - t0, "new": t2 - t1, "exr_extra": (t5 - t4) - (t4 - t3),
                     "bytes_old": (tmp / "old.exr").stat().st_size, "bytes_new": (tmp / "new.exr").stat().st_size,
                     "flow_px": float(np.median(np.hypot(*new["flow"][hit].T))) if hit.any() else 0.0})
        print(f"frame {i}: render {rows[-1]['render']:.3f} s, normal+flow+backward_flow {rows[-1]['new']:.3f} s, "
              f"extra EXR write {rows[-1]['exr_extra']:.3f} s, median flow {rows[-1]['flow_px']:.1f} px", flush=True)
    med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
    print(f"\n{args.preset} site, seed {args.seed}, {w}x{h}, {len(rows)} frames, {sim.render_device}, "
          f"{len(sim.object_names)} objects")
    print(f"preview render:                         {med['render']:.3f} s")
    print(f"normal + flow + backward_flow:          {med['new']:.3f} s  ({100 * med['new'] / med['render']:.1f}% of the render)")
    print(f"  + their EXR channels (ZIP) written:   {med['exr_extra']:.3f} s  "
          f"({100 * (med['new'] + med['exr_extra']) / med['render']:.1f}% with the writing)")
    print(f"frame EXR size: {med['bytes_old'] / 1e6:.2f} MB without them, {med['bytes_new'] / 1e6:.2f} MB with them")


if __name__ == "__main__":
    main()
