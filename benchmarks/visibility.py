"""Visibility throughput: Simulator.compute_point_cloud vs a Python loop over BVHTree.ray_cast.

Builds a scene of >= 1M triangles in code (a subdivided ground, dense spheres and boxes, a few
moving objects), samples >= 1M surface points, and measures in one run:
- points tested per second by ``compute_point_cloud`` (all N points, several poses);
- points tested per second by the reference: one ``BVHTree.ray_cast`` per point in Python
  (on a random subset), and the agreement of both answers on that subset;
- exploration steps per second without RGB (a move or turn + ``compute_point_cloud``).

Usage: .venv/bin/python benchmarks/visibility.py [--subset 20000] [--poses 10]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.blender import session  # noqa: E402  (bpy first)

bpy = session.bpy
import numpy as np  # noqa: E402

from generator import Simulator  # noqa: E402
from generator.geometry.raycast import OCCLUSION_TOL_ABS, OCCLUSION_TOL_REL  # noqa: E402


def build_scene(path: Path) -> None:
    session.new_empty_file()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 640, 480
    with session.quiet():
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=300, y_subdivisions=300, size=120)
        bpy.context.active_object.name = "Ground"
        rng = np.random.default_rng(0)
        for k in range(48):
            x, y = rng.uniform(-50, 50, 2)
            bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=5, radius=rng.uniform(1, 4), location=(x, y, 2))
            bpy.context.active_object.name = "Boulder"
        for k in range(60):
            x, y = rng.uniform(-50, 50, 2)
            bpy.ops.mesh.primitive_cube_add(size=1, location=(x, y, 3))
            o = bpy.context.active_object
            o.name = "Container"
            o.scale = (6, 2.4, 2.6)
            mod = o.modifiers.new("sub", "SUBSURF")
            mod.subdivision_type = "SIMPLE"
            mod.levels = mod.render_levels = 5
        for k in range(4):
            bpy.ops.mesh.primitive_cube_add(size=2, location=(-40 + 20 * k, -20, 1.5))
            t = bpy.context.active_object
            t.name = "Truck"
            t.keyframe_insert("location", frame=1)
            t.location.y += 30
            t.keyframe_insert("location", frame=200)
        bpy.ops.object.camera_add(location=(0, -55, 8), rotation=(math.radians(80), 0, 0))
        scene.camera = bpy.context.active_object
        scene.camera.data.clip_end = 1000
    session.save_blend(path)


def reference_visibility(sim: Simulator, points: np.ndarray) -> tuple[np.ndarray, float]:
    """One BVHTree.ray_cast per point, in a Python loop (the reference approach)."""
    from mathutils import Vector
    from mathutils.bvhtree import BVHTree

    verts, faces, offset = [], [], 0
    for part in sim._parts:  # the same world triangles the simulator uses
        verts.append(part.world_vertices())
        faces.append(part.faces + offset)
        offset += len(part.vertices)
    tree = BVHTree.FromPolygons(np.concatenate(verts).tolist(), np.concatenate(faces).tolist(), all_triangles=True)
    pose = sim.get_world_from_camera()
    origin = Vector(pose[:3, 3])
    uv, z = sim.project(points)
    near, far = sim.clip_start, min(sim.clip_end, sim.max_pcl_depth)
    in_view = (z > near) & (z <= far) & (uv[:, 0] >= 0) & (uv[:, 0] < sim.width) & (uv[:, 1] >= 0) & (uv[:, 1] < sim.height)
    out = np.zeros(len(points), dtype=bool)
    t0 = time.perf_counter()
    for i, p in enumerate(points):
        d = Vector(p) - origin
        dist = d.length
        hit, _, _, _ = tree.ray_cast(origin, d / dist, dist - (OCCLUSION_TOL_ABS + OCCLUSION_TOL_REL * dist))
        out[i] = hit is None
    elapsed = time.perf_counter() - t0
    return out & in_view, elapsed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subset", type=int, default=20000, help="points timed with the reference loop")
    ap.add_argument("--poses", type=int, default=10, help="poses timed with compute_point_cloud")
    ap.add_argument("--density", type=float, default=45.0, help="surface points per square metre")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.blend"
        t0 = time.perf_counter()
        build_scene(path)
        t_build = time.perf_counter() - t0
        t0 = time.perf_counter()
        sim = Simulator(path, points_density=args.density, seed=0)
        t_init = time.perf_counter() - t0
    n_tri = sum(len(p.faces) for p in sim._parts)
    n = sim.num_points
    print(f"scene: {n_tri:,} triangles, {n:,} points, {len(sim.dynamic_objects)} dynamic objects; "
          f"built in {t_build:.1f} s, Simulator() in {t_init:.1f} s")

    rng = np.random.default_rng(1)
    sim.compute_point_cloud()  # warm-up (first dynamic structure build)
    times, stats = [], []
    for k in range(args.poses):
        sim.turn_camera_right(360 / args.poses)
        t0 = time.perf_counter()
        sim.compute_point_cloud()
        times.append(time.perf_counter() - t0)
        s = sim.last_visibility
        stats.append((s.in_view, s.culled_backfacing, s.rays, s.visible))
    ours = n / np.median(times)
    st = np.mean(stats, axis=0)
    print(f"ours: {np.median(times) * 1e3:.0f} ms per call, {ours / 1e6:.2f} M points/s "
          f"(mean per pose: {st[0]:,.0f} in view, {st[1]:,.0f} culled as back faces, {st[2]:,.0f} rays, {st[3]:,.0f} visible)")

    pts, _, vis = sim.compute_point_cloud(update_mask=False)
    subset = rng.choice(n, size=min(args.subset, n), replace=False)
    ref_vis, ref_time = reference_visibility(sim, pts[subset])
    ref_rate = len(subset) / ref_time
    agree = float((ref_vis == vis[subset]).mean())
    print(f"reference (BVHTree.ray_cast loop): {ref_rate / 1e6:.3f} M points/s on {len(subset):,} points")
    print(f"speed-up: {ours / ref_rate:.0f}x; agreement with the reference on the subset: {agree * 100:.3f}%")

    # exploration steps without RGB: random forward moves and turns + compute_point_cloud
    sim.set_world_from_camera(sim.get_world_from_camera(), check_collisions=False)
    t0 = time.perf_counter()
    steps = 20
    for k in range(steps):
        if rng.random() < 0.5:
            sim.move_camera_forward(2.0)
        else:
            sim.turn_camera_right(rng.choice([-30.0, 30.0]))
        sim.compute_point_cloud()
    step_rate = steps / (time.perf_counter() - t0)
    print(f"exploration: {step_rate:.1f} steps/s (move or turn + compute_point_cloud, {n:,} points)")


if __name__ == "__main__":
    main()
