"""Exact float64 distances from points to the triangles within a radius of them (numba,
compiled once and cached on disk).

Embree's closest-point query (open3d) computes in float32, which on needle triangles (a
scaffold tube's 15 m x 1.5 cm faces, a crane jib's) is off by millimetres to centimetres.
Where a distance must be exact (the timeline's added / removed points, generator/scene/
changes.py), :func:`near_distances` takes every triangle whose box, grown by ``radius``,
meets the grid cell of a point, and keeps the smallest float64 point-to-triangle distance
(:func:`point_triangle_sq`: the nearest of the three edges and, when the foot of the
perpendicular falls inside the triangle, of its plane). Triangles
farther than ``radius`` may be among the candidates; no triangle within ``radius`` is
missed, so a finite answer <= ``radius`` is the exact distance to the whole surface.

Only IEEE float64 multiplies, adds, compares and one square root, in a fixed order, without
``fastmath``: the same bits on every CPU (tests/test_visibility.py checks the compiled code
for fused multiply-adds).
"""

from __future__ import annotations

import math

import numba
import numpy as np

_SPAN = 1 << 20  # cells per axis that a key holds (21 bits each, offset to be non-negative)


@numba.njit(cache=True, nogil=True)
def _dot(ax, ay, az, bx, by, bz):
    return (ax * bx + ay * by) + az * bz


@numba.njit(cache=True, nogil=True)
def _off_sq(qx, qy, qz, s, ex, ey, ez):
    """|q - s e|^2: the squared distance from p to the point at s along an edge e, q = p - start."""
    rx, ry, rz = qx - s * ex, qy - s * ey, qz - s * ez
    return _dot(rx, ry, rz, rx, ry, rz)


@numba.njit(cache=True, nogil=True)
def _edges_sq(px, py, pz, tri):
    """Squared distance from p to the nearest of the triangle's three edges (segments)."""
    best = math.inf
    for i in range(3):
        j = (i + 1) % 3
        ex, ey, ez = tri[j, 0] - tri[i, 0], tri[j, 1] - tri[i, 1], tri[j, 2] - tri[i, 2]
        qx, qy, qz = px - tri[i, 0], py - tri[i, 1], pz - tri[i, 2]
        ee = _dot(ex, ey, ez, ex, ey, ez)
        s = 0.0 if ee == 0.0 else min(max(_dot(qx, qy, qz, ex, ey, ez) / ee, 0.0), 1.0)
        best = min(best, _off_sq(qx, qy, qz, s, ex, ey, ez))
    return best


@numba.njit(cache=True, nogil=True)
def _side(nx, ny, nz, ex, ey, ez, qx, qy, qz):
    """n . (e x q): >= 0 when q lies on the inner side of the edge e (seen along n)."""
    return _dot(nx, ny, nz, ey * qz - ez * qy, ez * qx - ex * qz, ex * qy - ey * qx)


@numba.njit(cache=True, nogil=True)
def point_triangle_sq(px, py, pz, tri):
    """Squared float64 distance from point p to the triangle ``tri`` (3, 3): the nearest of its
    three edges, and of its plane when the foot of the perpendicular falls inside it (the signs
    of n . (e x (p - v)) on its three edges). Ericson's region tests are not used: on needles
    they cancel (off by millimetres at a sine of 1e-6 at a corner)."""
    ax, ay, az = tri[0, 0], tri[0, 1], tri[0, 2]
    abx, aby, abz = tri[1, 0] - ax, tri[1, 1] - ay, tri[1, 2] - az
    acx, acy, acz = tri[2, 0] - ax, tri[2, 1] - ay, tri[2, 2] - az
    edges = _edges_sq(px, py, pz, tri)
    nx, ny, nz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
    nn = _dot(nx, ny, nz, nx, ny, nz)
    # a sine below 1e-8 at a (a needle or a segment): the edges are within that share of its
    # size of every point of it, nearer than the round-off of its normal would allow
    if nn <= 1e-16 * (_dot(abx, aby, abz, abx, aby, abz) * _dot(acx, acy, acz, acx, acy, acz)):
        return edges
    apx, apy, apz = px - ax, py - ay, pz - az
    bx, by, bz = tri[1, 0], tri[1, 1], tri[1, 2]
    cx, cy, cz = tri[2, 0], tri[2, 1], tri[2, 2]
    if (_side(nx, ny, nz, abx, aby, abz, apx, apy, apz) >= 0.0
            and _side(nx, ny, nz, cx - bx, cy - by, cz - bz, px - bx, py - by, pz - bz) >= 0.0
            and _side(nx, ny, nz, ax - cx, ay - cy, az - cz, px - cx, py - cy, pz - cz) >= 0.0):
        h = _dot(nx, ny, nz, apx, apy, apz)
        return min(edges, h * h / nn)
    return edges


@numba.njit(cache=True, nogil=True)
def _key(ix, iy, iz):
    return ((ix + _SPAN) * (2 * _SPAN) + (iy + _SPAN)) * (2 * _SPAN) + (iz + _SPAN)


@numba.njit(cache=True, nogil=True)
def cell_pairs(tri, lo, hi, cell, cells, fill, counts, members):
    """For each triangle, each grid cell of ``cells`` (sorted keys) that its box [lo, hi]
    meets: count it (``fill`` False) or write the triangle into ``members`` (True)."""
    for t in range(len(tri)):
        i0, i1 = math.floor(lo[t, 0] / cell), math.floor(hi[t, 0] / cell)
        j0, j1 = math.floor(lo[t, 1] / cell), math.floor(hi[t, 1] / cell)
        k0, k1 = math.floor(lo[t, 2] / cell), math.floor(hi[t, 2] / cell)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                for k in range(k0, k1 + 1):
                    key = _key(i, j, k)
                    c = np.searchsorted(cells, key)
                    if c < len(cells) and cells[c] == key:
                        if fill:
                            members[counts[c]] = t
                        counts[c] += 1


@numba.njit(cache=True, nogil=True, parallel=True)
def nearest_in_cells(points, point_cell, start, members, tri, out):
    for p in numba.prange(len(points)):  # each point on its own: the same answer on any thread count
        c = point_cell[p]
        best = math.inf
        for m in range(start[c], start[c + 1]):
            best = min(best, point_triangle_sq(points[p, 0], points[p, 1], points[p, 2], tri[members[m]]))
        out[p] = math.sqrt(best)


def near_distances(points: np.ndarray, triangles: np.ndarray, radius: float) -> np.ndarray:
    """(N,) float64: the exact distance in metres from each point (N, 3) to the nearest of
    ``triangles`` (T, 3, 3) when some triangle lies within ``radius`` metres of it; otherwise
    a distance > ``radius`` (to some triangle) or inf (see the module's docstring)."""
    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    tri = np.ascontiguousarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    out = np.full(len(p), np.inf)
    if len(p) == 0 or len(tri) == 0:
        return out
    # cells about the radius across (fewer candidates per cell), grown where coordinates are
    # so large that the keys would not hold them
    extent = max(float(np.abs(p).max()), float(np.abs(tri).max()) + radius)
    cell = max(float(radius), extent / (_SPAN - 2), 1e-9)
    ijk = np.floor(p / cell).astype(np.int64)
    point_keys = _key(ijk[:, 0], ijk[:, 1], ijk[:, 2])  # the kernels' own key, on whole arrays
    cells, point_cell = np.unique(point_keys, return_inverse=True)
    lo, hi = tri.min(axis=1) - radius, tri.max(axis=1) + radius
    counts = np.zeros(len(cells), np.int64)
    cell_pairs(tri, lo, hi, cell, cells, False, counts, np.zeros(0, np.int64))
    start = np.zeros(len(cells) + 1, np.int64)
    np.cumsum(counts, out=start[1:])
    members = np.empty(start[-1], np.int64)
    cursor = start[:-1].copy()
    cell_pairs(tri, lo, hi, cell, cells, True, cursor, members)
    nearest_in_cells(p, point_cell.reshape(-1).astype(np.int64), start, members, tri, out)
    return out

