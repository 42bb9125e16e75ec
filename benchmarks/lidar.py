"""LiDAR sweep speed: ours against the plain way, on the medium site of ``--seed``.

One sweep of ``--sensor`` (default os1-128: 128 beams x 2048 columns) from the sensor at
1.8 m above the site's south gate, looking north, dynamic objects at the first frame:
- ours: ``generator.lidar.scanner.Scanner.sweep`` (exact float64 hits on the Simulator's
  two Embree structures, per-face optics, intensity, detection rules, noise, the sensor's
  pose per column, labels and object ids);
- plain: one open3d ``RaycastingScene`` of every part's world triangles (built once, not
  timed), ``cast_rays`` on the same rays (the sweep's world rays, float32), then class and
  object ids by looking up the geometry hit (what a user writes with open3d: no physics,
  float32 hits).
The two take turns going first; the figures are the median of ``--rounds``. Rays per second
counts every beam fired; returns per second the beams that came back (ours: after the
detection rules; plain: every hit).

Usage: .venv/bin/python benchmarks/lidar.py [--sensor os1-128] [--rounds 3] [--seed 0]
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

from generator import Simulator  # noqa: E402


def plain_scene(parts):
    """open3d's way, built once: one structure of every part's world triangles, and the part
    of each geometry id."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    owner = []
    for i, p in enumerate(parts):
        if len(p.faces):
            scene.add_triangles(o3d.core.Tensor(p.world_vertices().astype(np.float32)),
                                o3d.core.Tensor(p.faces.astype(np.uint32)))
            owner.append(i)
    return scene, np.asarray(owner)


def plain(built, label_of_part, origins, directions):
    """open3d's way: float32 rays, labels by geometry id (returns the count of hits)."""
    import open3d as o3d

    scene, owner = built
    rays = np.concatenate([origins, directions], axis=1).astype(np.float32)
    ans = scene.cast_rays(o3d.core.Tensor(rays))
    t = ans["t_hit"].numpy()
    hit = np.isfinite(t)
    part = owner[ans["geometry_ids"].numpy()[hit]]
    labels, instances = label_of_part[part], part  # noqa: F841  (what the user keeps)
    return int(hit.sum())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sensor", default="os1-128")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/buildee-render-bench"),
                    help="where the site is built once and reused")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from render import medium_site

    from generator.geometry.raycast import SceneGeometry
    from generator.geometry.motion import MotionTrack
    from generator.lidar.scanner import Scanner
    from generator.lidar.sensors import emission, lidar

    sim = Simulator(medium_site(args.seed, args.cache), points_density=0.1, seed=args.seed)
    sim.set_frame(sim.frame_range[0])
    parts = sim.scene_parts()
    label_of_part = np.array([sim.label_ids[p.label] for p in parts])
    sensor = lidar(args.sensor)
    pose = np.eye(4)
    pose[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # x (forward) north
    pose[:3, 3] = (0.0, -24.0, 1.8)
    body = MotionTrack(np.array([0.0]), pose[None])
    beams = emission(sensor, 0)
    directions = beams.directions @ pose[:3, :3].T
    origins = np.broadcast_to(pose[:3, 3], directions.shape)
    scanner = Scanner(SceneGeometry(parts), label_of_part, np.arange(len(parts)), args.seed)
    scanner.sweep(sensor, 0, 0.0, body)  # structures built, kernels compiled
    built = plain_scene(parts)
    plain(built, label_of_part, origins, directions)
    times, returns = {"ours": [], "plain": []}, {}
    for r in range(args.rounds):
        for who in ("ours", "plain") if r % 2 == 0 else ("plain", "ours"):
            t0 = time.perf_counter()
            if who == "ours":
                returns[who] = len(scanner.sweep(sensor, 0, 0.0, body).scan)
            else:
                returns[who] = plain(built, label_of_part, origins, directions)
            times[who].append(time.perf_counter() - t0)
    rays = len(beams.time)
    print(f"{sensor.name}: {rays:,} rays a sweep, medium seed {args.seed} ({len(parts)} parts), median of {args.rounds}")
    print(f"{'':8}{'s a sweep':>10}{'rays/s':>14}{'returns':>10}{'returns/s':>14}")
    for who in ("ours", "plain"):
        t = statistics.median(times[who])
        print(f"{who:8}{t:>10.3f}{rays / t:>14,.0f}{returns[who]:>10,}{returns[who] / t:>14,.0f}")
    print(f"ours / plain time: {statistics.median(times['ours']) / statistics.median(times['plain']):.2f}x")


if __name__ == "__main__":
    main()
