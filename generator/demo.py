"""Interim main job (until the batch generator of issue #5): build and explore each seed's site.

For each seed it builds the procedural construction site (``generator.scene``, medium
preset) into ``<out>/seed_<seed>/`` (site.blend, preview.png, map.png, site.json), explores
it with a seeded random walk of the paper's five actions through the Simulator (points
visible within 20 m) and writes ``coverage.json`` (coverage after every step: share of
surface points observed at least once, 0 to 1) and ``walk_map.png`` (the walk on the map).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from .geometry.seeding import stream


def run_seed(seed: int, out: Path, steps: int, progress) -> dict:
    from . import Simulator
    from .scene import build_site, plan_site, site_params
    from .scene.site_map import draw_map

    folder = out / f"seed_{seed:06d}"
    t0 = time.perf_counter()
    site = build_site(seed, "medium", folder)
    sim = Simulator(site.blend, points_density=5.0, seed=seed, max_pcl_depth=20.0)
    sim.respawn_camera()
    rng = stream(seed, "demo-walk")
    curve, path = [], [sim.get_world_from_camera()[:3, 3]]
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
        path.append(sim.get_world_from_camera()[:3, 3])
        progress.update(1)
    draw_map(plan_site(seed, site_params("medium")), folder / "walk_map.png", trajectory=np.array(path))
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
