"""Camera spawn points: free positions inside a closed spawn volume."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from . import portable_math
from .camera import heading_pose
from .parts import MeshPart
from .raycast import SceneGeometry


class SpawnVolumeError(ValueError):
    """The CameraSpawn object cannot provide spawn points."""


def sample_spawn_points(
    volume: MeshPart,
    scene: SceneGeometry,
    radius: float,
    rng: np.random.Generator,
    count: int = 1024,
    max_batches: int = 20,
    batch: int = 4096,
) -> np.ndarray:
    """Up to ``count`` points (M, 3) uniformly distributed inside ``volume`` where a camera
    sphere of ``radius`` touches no scene geometry and is not inside a solid."""
    if not volume.closed:
        raise SpawnVolumeError(
            f"{volume.name!r} is not a closed mesh, so it has no inside; make it watertight (e.g. a cube)"
        )
    inside_test = SceneGeometry([volume])
    lo, hi = volume.vertices.min(axis=0), volume.vertices.max(axis=0)
    found = []
    total = 0
    for _ in range(max_batches):
        cand = lo + rng.random((batch, 3)) * (hi - lo)
        cand = cand[inside_test.inside_solid(cand)]
        if len(cand):
            cand = cand[scene.distance(cand) >= radius]
        if len(cand):
            cand = cand[~scene.inside_solid(cand)]
        found.append(cand)
        total += len(cand)
        if total >= count:
            break
    points = np.concatenate(found)[:count]
    if len(points) == 0:
        raise SpawnVolumeError(f"{volume.name!r} contains no free space for a camera of radius {radius} m")
    return points


def respawn_pose(spawn_points: np.ndarray, current_pose: np.ndarray, rng: np.random.Generator,
                 is_free: Callable[[np.ndarray], bool], tries: int = 100) -> np.ndarray:
    """A pose at a random spawn point that ``is_free`` (the first of ``tries`` draws that is;
    after ``tries`` misses, one drawn among all the free spawn points) with a random
    heading, the pitch of ``current_pose`` kept and no roll. SpawnVolumeError if no spawn
    point is free (e.g. ``collision_radius`` was raised after the points were sampled)."""
    forward = current_pose[:3, 2]
    limit = portable_math.atan2(0.999, math.sqrt(1.0 - 0.999 * 0.999))  # asin 0.999
    pitch = float(np.clip(portable_math.atan2(forward[2], portable_math.hypot(forward[0], forward[1])), -limit, limit))
    for _ in range(tries):
        p = spawn_points[rng.integers(len(spawn_points))]
        yaw = rng.uniform(0.0, 2 * math.pi)
        if is_free(p):
            return heading_pose(p, yaw, pitch)
    free = [q for q in spawn_points if is_free(q)]
    if not free:
        raise SpawnVolumeError(f"none of the {len(spawn_points)} spawn points is free for the camera's current "
                               "collision radius; lower collision_radius or make a new Simulator with it")
    return heading_pose(free[rng.integers(len(free))], rng.uniform(0.0, 2 * math.pi), pitch)
