"""Camera spawn points: free positions inside a closed spawn volume."""

from __future__ import annotations

import numpy as np

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
