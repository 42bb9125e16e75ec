"""Exact float64 geometry used as a measuring stick in tests (slow, brute force)."""

import numpy as np


def closest_point_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest points (M, 3) on triangles (a, b, c) (M, 3 each) to points p (M, 3), float64
    (the Voronoi-region method from Ericson, Real-Time Collision Detection, 5.1.5)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 1.0 / (va + vb + vc)
        out = a + ab * (vb * denom)[:, None] + ac * (vc * denom)[:, None]  # inside the face
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    cases = [
        ((d1 <= 0) & (d2 <= 0), a),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t_ab[:, None]),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t_ac[:, None]),
        ((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), b + (c - b) * t_bc[:, None]),
    ]
    done = np.zeros(len(p), dtype=bool)
    for cond, value in cases:
        use = cond & ~done
        out[use] = value[use]
        done |= use
    return out


def distance_to_mesh(points: np.ndarray, triangles: np.ndarray, chunk: int = 200_000) -> np.ndarray:
    """Exact distance (N,) from points (N, 3) to the nearest of triangles (T, 3, 3)."""
    points = np.asarray(points, dtype=np.float64)
    tri = np.asarray(triangles, dtype=np.float64)
    best = np.full(len(points), np.inf)
    step = max(1, chunk // max(len(tri), 1))
    for s in range(0, len(points), step):
        p = points[s : s + step]
        pp = np.repeat(p, len(tri), axis=0)
        t = np.tile(tri, (len(p), 1, 1))
        q = closest_point_on_triangles(pp, t[:, 0], t[:, 1], t[:, 2])
        d = np.linalg.norm(pp - q, axis=1).reshape(len(p), len(tri))
        best[s : s + step] = d.min(axis=1)
    return best


def scene_triangles(parts) -> np.ndarray:
    return np.concatenate([p.world_vertices()[p.faces] for p in parts])


def first_hits(origins, dirs, triangles):
    """Brute force: nearest t > 0 of every ray (N, 3) on triangles (T, 3, 3), float64
    Moller-Trumbore, and the unit normal of the triangle hit (NaN rows for none)."""
    a, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    best_t, best_n = np.full(len(dirs), np.inf), np.full((len(dirs), 3), np.nan)
    normals = np.cross(e1, e2)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    for k in range(len(triangles)):
        p = np.cross(dirs, e2[k])
        det = p @ e1[k]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = origins - a[k]
            u = np.einsum("ij,ij->i", s, p) / det
            q = np.cross(s, e1[k])
            v = np.einsum("ij,ij->i", dirs, q) / det
            t = (q @ e2[k]) / det
        ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < best_t)
        best_t[ok], best_n[ok] = t[ok], normals[k]
    return best_t, best_n


# An independent float64 point-to-triangle distance (plane inside the triangle, else the nearest
# edge), for generator/geometry/near_distance.py and the timeline's added / removed points.
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
