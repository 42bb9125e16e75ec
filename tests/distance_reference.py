"""An independent float64 point-to-triangle distance in numpy, for the tests of the exact
distances (generator/geometry/near_distance.py) and of the timeline's added / removed points."""

import numpy as np


def segment_distance(p, a, b):
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-30), 0, 1)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def exact_distance(point, tri):
    """Distance from one point to the nearest of triangles (M, 3, 3), in numpy (plane inside the
    triangle, else the nearest edge); an independent twin of the distances under test."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    p = np.broadcast_to(point, a.shape)
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    ok = norm > 1e-15
    n = n / np.where(ok, norm, 1.0)[:, None]
    h = np.einsum("ij,ij->i", p - a, n)
    q = p - h[:, None] * n
    inside = ok & np.all([np.einsum("ij,ij->i", np.cross(v1 - v0, q - v0), n) >= 0
                          for v0, v1 in ((a, b), (b, c), (c, a))], axis=0)
    plane = np.where(inside, np.abs(h), np.inf)
    return float(np.min(np.minimum(plane, np.minimum.reduce([segment_distance(p, a, b), segment_distance(p, b, c),
                                                              segment_distance(p, c, a)]))))
