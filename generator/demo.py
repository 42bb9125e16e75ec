"""Interim main job (until the batch generator of issue #5): a small Simulator demo per seed.

For each seed it builds a toy site in code (ground, seeded containers and cabins, a truck
driving through, a CameraSpawn volume), saves it as ``<out>/seed_<seed>/scene.blend``,
explores it with a seeded random walk and writes ``coverage.json`` (coverage after every
step, share of surface points observed, 0 to 1).
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from .blender import session
from .geometry.seeding import stream

bpy = session.bpy


def _box(name: str, size, location, yaw: float = 0.0):
    sx, sy, sz = (s / 2 for s in size)
    verts = [(x, y, z) for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler[2] = yaw
    return obj


def build_toy_site(seed: int, path: Path) -> None:
    """A 60 m toy site: not the procedural generator (issue #4), just enough to explore."""
    rng = stream(seed, "demo-site")
    session.new_empty_file()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 320, 240
    _box("Ground", (60, 60, 0.2), (0, 0, -0.1))
    for k in range(int(rng.integers(8, 14))):
        kind = rng.choice(["Container", "Cabin"])
        size = (6.06, 2.44, 2.59) if kind == "Container" else (6.0, 2.4, 2.7)
        x, y = rng.uniform(-25, 25, 2)
        _box(kind, size, (x, y, size[2] / 2), float(rng.uniform(0, math.pi)))
    truck = _box("Truck", (8.5, 2.5, 3.3), (-25, float(rng.uniform(-20, 20)), 1.65))
    truck.keyframe_insert("location", frame=1)
    truck.location.x = 25
    truck.keyframe_insert("location", frame=250)
    spawn = _box("CameraSpawn", (50, 50, 6), (0, 0, 6))
    spawn.hide_render = True
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.location = (0, -28, 4)
    cam.rotation_euler = (math.radians(85), 0, 0)
    scene.camera = cam
    session.save_blend(path)


def run_seed(seed: int, out: Path, steps: int, progress) -> dict:
    from . import Simulator

    folder = out / f"seed_{seed:06d}"
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    build_toy_site(seed, folder / "scene.blend")
    sim = Simulator(folder / "scene.blend", points_density=5.0, seed=seed, max_pcl_depth=20.0)
    sim.respawn_camera()
    rng = stream(seed, "demo-walk")
    curve = []
    sim.compute_point_cloud()
    curve.append(sim.coverage)
    for _ in range(steps):
        action = int(rng.integers(5))
        if action == 0:
            sim.move_camera_forward(2.0)
        elif action in (1, 2):
            sim.move_camera_right(2.0 if action == 1 else -2.0)
        else:
            sim.turn_camera_right(30.0 if action == 3 else -30.0)
        sim.step_frame()
        sim.compute_point_cloud()
        curve.append(sim.coverage)
        progress.update(1)
    result = {
        "seed": seed,
        "points": sim.num_points,
        "labels": sim.labels,
        "steps": steps,
        "coverage": curve,
        "coverage_units": "share of surface points observed at least once (0..1), after each step",
        "auc": float(np.trapezoid(curve, np.linspace(0, 1, len(curve)))),
    }
    (folder / "coverage.json").write_text(json.dumps(result, indent=1))
    result["seconds"] = time.perf_counter() - t0
    return result
