"""Area-weighted, seeded sampling of points on triangle surfaces."""

from __future__ import annotations

import numpy as np


def triangle_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Areas (T,) in square metres of the triangles ``faces`` (T, 3) over ``vertices`` (V, 3)."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def sample_triangles(
    vertices: np.ndarray, faces: np.ndarray, density: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Sample points uniformly on a triangle mesh at ``density`` points per square metre.

    The number of points is ``floor(density * area + u)`` with ``u`` uniform in [0, 1), so
    its expectation is exactly ``density * area`` even for small objects. Returns
    ``(points (n, 3) float64, face_index (n,) int64)``.
    """
    faces = np.asarray(faces, dtype=np.int64)
    vertices = np.asarray(vertices, dtype=np.float64)
    if len(faces) == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    areas = triangle_areas(vertices, faces)
    total = float(areas.sum())
    n = int(np.floor(density * total + rng.random()))
    if n == 0 or total <= 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    cdf = np.cumsum(areas)
    face = np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right")
    face = np.minimum(face, len(faces) - 1)
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    a, b, c = (vertices[faces[face, k]] for k in range(3))
    points = (1 - r1)[:, None] * a + (r1 * (1 - r2))[:, None] * b + (r1 * r2)[:, None] * c
    return points, face
