"""Disk size of the point tracks: our sparse tracks.h5 against a dense (T, N) layout.

A real medium site (seed 0) with about 1 M surface points, a 300-frame spline fly-through,
visibility from the Simulator (no rendering). The sparse file is written by
``exporters.tracks.TrackWriter``; the dense reference stores, like a TAP-Vid file, every
point's pixel position and depth at every frame plus a visibility flag, with the same
gzip compression and frame-sized chunks.

Usage: .venv/bin/python benchmarks/track_size.py [--points 1000000] [--frames 300]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from generator import Simulator  # noqa: E402
from generator.blender import session  # noqa: E402,F401  (bpy first)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--frames", type=int, default=300)
    args = ap.parse_args()
    import h5py
    import numpy as np
    from tqdm import tqdm

    from exporters.tracks import TrackWriter
    from generator.batch.config import plan_trajectory
    from generator.geometry.camera import project
    from generator.geometry.sampling import triangle_areas
    from generator.scene import build_site

    tmp = Path(tempfile.mkdtemp())
    site = build_site(0, "medium", tmp / "scene", preview=False, frames=max(250, args.frames))
    probe = Simulator(site.blend, points_density=0.01, seed=0)
    area = sum(triangle_areas(p.vertices, p.faces).sum() for p in probe.scene_parts())
    sim = Simulator(site.blend, points_density=args.points / area, seed=0, max_pcl_depth=60.0)
    start = sim.respawn_camera()
    traj = plan_trajectory("spline", sim, sim.spawn_points, start, 0, args.frames, 10.0)
    N, T = sim.num_points, len(traj)
    sparse = TrackWriter(tmp / "tracks.h5", sim.point_table(), sim.dynamic_objects, sim.labels, sim.K,
                         sim.width, sim.height)
    dense = h5py.File(tmp / "dense.h5", "w")
    kw = {"compression": "gzip", "compression_opts": 4}
    d_xy = dense.create_dataset("xy", (T, N, 2), "f4", chunks=(1, min(N, 1 << 16), 2), **kw)
    d_z = dense.create_dataset("depth", (T, N), "f4", chunks=(1, min(N, 1 << 18)), **kw)
    d_vis = dense.create_dataset("visible", (T, N), bool, chunks=(1, min(N, 1 << 20)), **kw)
    t_sparse = t_dense = 0.0
    observations = 0
    for t, pose in enumerate(tqdm(traj.poses, desc="frames")):
        sim.set_frame(1 + t)
        sim.set_world_from_camera(pose, check_collisions=False)
        points, _, visible = sim.compute_point_cloud()
        observations += int(visible.sum())
        t0 = time.perf_counter()
        sparse.add_frame(float(traj.timestamps[t]), pose, points, visible, sim.dynamic_object_matrices(), sim.coverage)
        t1 = time.perf_counter()
        xy, z = project(points, pose, sim.K)
        d_xy[t], d_z[t], d_vis[t] = xy.astype(np.float32), z.astype(np.float32), visible
        t_dense += time.perf_counter() - t1
        t_sparse += t1 - t0
    t0 = time.perf_counter()
    sparse.close()
    t_sparse += time.perf_counter() - t0
    dense.close()
    mb = 1e6
    s_size, d_size = (tmp / "tracks.h5").stat().st_size, (tmp / "dense.h5").stat().st_size
    raw = T * N * (2 * 4 + 4 + 1)
    print(f"\n{N:,} points x {T} frames, {observations:,} visible observations "
          f"({observations / (N * T):.2%} of T x N), 640x480")
    print("| layout | file size | bytes per visible observation | write time |")
    print("|---|---|---|---|")
    print(f"| dense (T, N): xy f4, depth f4, visible bool, gzip | {d_size / mb:,.0f} MB | {d_size / observations:.1f} | {t_dense:.0f} s |")
    print(f"| dense, uncompressed (computed) | {raw / mb:,.0f} MB | {raw / observations:.1f} | - |")
    print(f"| ours: sparse tracks.h5 (everything, incl. points, matrices, TAP-Vid subset) | {s_size / mb:,.0f} MB | "
          f"{s_size / observations:.1f} | {t_sparse:.0f} s |")
    print(f"ratio dense (gzip) / ours: {d_size / s_size:.1f}x; uncompressed dense / ours: {raw / s_size:.1f}x")


if __name__ == "__main__":
    main()
