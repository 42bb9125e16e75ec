"""Float64 arithmetic of the pixel ground truth that must give the same bits on every machine
(numba, compiled once and cached on disk).

numpy hands ``@`` to BLAS and Embree computes its ray distances in float32 code that it
compiles per instruction set; both pick their kernel, and so their rounding, by the CPU. The
kernels here use IEEE float64 multiplies and adds in a fixed order: numba without
``fastmath`` neither reorders nor fuses multiply-adds (``tests/test_ground_truth.py`` checks
the compiled code), so each result is the same bits as numpy evaluating the same expression
element by element, on any CPU.

- :func:`rows_times`: ``v @ m`` for rows v (N, 3) and 3x3 m, as (v0 m0k + v1 m1k) + v2 m2k;
- :func:`batch_rows_times`: the same with one matrix per row;
- :func:`plane_hits`: where a ray meets a triangle's plane, how far outside the triangle
  that is, and the triangle's normal;
- :func:`proposed_hits`: the same for every ray of a cast on the triangle Embree proposed;
- :func:`float32_rays`: a cast's float64 rays as Embree's float32 ones;
- :func:`farther_than`, :func:`take_rays`, :func:`box_of`: the cast's small steps in one pass
  (numpy's fancy gathers and axis-0 reductions of (N, 3) arrays are 10-25 times slower).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def rows_times(v: np.ndarray, m: np.ndarray, out: np.ndarray) -> None:
    """out[i, k] = (v[i, 0] m[0, k] + v[i, 1] m[1, k]) + v[i, 2] m[2, k]; v, out (N, 3)."""
    for i in range(v.shape[0]):
        x0, x1, x2 = v[i, 0], v[i, 1], v[i, 2]
        for k in range(3):
            out[i, k] = (x0 * m[0, k] + x1 * m[1, k]) + x2 * m[2, k]


@numba.njit(cache=True, nogil=True)
def batch_rows_times(v: np.ndarray, m: np.ndarray, out: np.ndarray) -> None:
    """out[i, k] = (v[i, 0] m[i, 0, k] + v[i, 1] m[i, 1, k]) + v[i, 2] m[i, 2, k]."""
    for i in range(v.shape[0]):
        x0, x1, x2 = v[i, 0], v[i, 1], v[i, 2]
        for k in range(3):
            out[i, k] = (x0 * m[i, 0, k] + x1 * m[i, 1, k]) + x2 * m[i, 2, k]


@numba.njit(cache=True, nogil=True, inline="always")  # part of _plane_hit's compiled code
def _edge_side(px, py, pz, qx, qy, qz, x, y, z, nx, ny, nz):
    """((q - p) x (w - p)) . n for w = (x, y, z): >= 0 on the triangle's side of the edge
    p -> q (n = (b - a) x (c - a)); its distance from the edge line is this / (|n| |q - p|)."""
    ex, ey, ez = qx - px, qy - py, qz - pz
    wx, wy, wz = x - px, y - py, z - pz
    return (nx * (ey * wz - ez * wy) + ny * (ez * wx - ex * wz)) + nz * (ex * wy - ey * wx)


@numba.njit(cache=True, nogil=True, inline="always")  # part of _plane_hit's compiled code
def _beyond(side, px, py, pz, qx, qy, qz, length):
    """How far (metres, >= 0) a point of edge-side value ``side`` lies beyond the edge p -> q."""
    if side >= 0.0:
        return 0.0
    ex, ey, ez = qx - px, qy - py, qz - pz
    return -side / (length * math.sqrt((ex * ex + ey * ey) + ez * ez))


@numba.njit(cache=True, nogil=True, inline="always")  # part of plane_hits' compiled code
def _plane_hit(ox, oy, oz, dx, dy, dz, vertices, ia, ib, ic):
    """One ray and one triangle (rows ia, ib, ic of ``vertices``): (t, outside, nx, ny, nz,
    |n|) as :func:`plane_hits` describes them, n = (b - a) x (c - a) unnormalised."""
    ax, ay, az = np.float64(vertices[ia, 0]), np.float64(vertices[ia, 1]), np.float64(vertices[ia, 2])
    bx, by, bz = np.float64(vertices[ib, 0]), np.float64(vertices[ib, 1]), np.float64(vertices[ib, 2])
    cx, cy, cz = np.float64(vertices[ic, 0]), np.float64(vertices[ic, 1]), np.float64(vertices[ic, 2])
    e1x, e1y, e1z = bx - ax, by - ay, bz - az
    e2x, e2y, e2z = cx - ax, cy - ay, cz - az
    nx = e1y * e2z - e1z * e2y
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    num = (nx * (ax - ox) + ny * (ay - oy)) + nz * (az - oz)
    den = (nx * dx + ny * dy) + nz * dz
    if den != 0.0:
        t = num / den
    elif num != 0.0:
        t = math.inf
    else:
        t = math.nan
    length = math.sqrt((nx * nx + ny * ny) + nz * nz)
    outside = math.nan
    if length > 0.0 and math.isfinite(t):
        x, y, z = ox + t * dx, oy + t * dy, oz + t * dz
        s_ab = _edge_side(ax, ay, az, bx, by, bz, x, y, z, nx, ny, nz)
        s_bc = _edge_side(bx, by, bz, cx, cy, cz, x, y, z, nx, ny, nz)
        s_ca = _edge_side(cx, cy, cz, ax, ay, az, x, y, z, nx, ny, nz)
        outside = max(_beyond(s_ab, ax, ay, az, bx, by, bz, length),
                      _beyond(s_bc, bx, by, bz, cx, cy, cz, length),
                      _beyond(s_ca, cx, cy, cz, ax, ay, az, length))
    return t, outside, nx, ny, nz, length


@numba.njit(cache=True, nogil=True, inline="always")  # part of the kernels' compiled code
def _store_unit(unit, i, nx, ny, nz, length):
    """unit[i] = n / |n| (NaN when |n| = 0)."""
    if length > 0.0:
        unit[i, 0], unit[i, 1], unit[i, 2] = nx / length, ny / length, nz / length
    else:
        unit[i, 0], unit[i, 1], unit[i, 2] = math.nan, math.nan, math.nan


@numba.njit(cache=True, nogil=True)
def plane_hits(origins: np.ndarray, directions: np.ndarray, vertices: np.ndarray, corners: np.ndarray,
               t: np.ndarray, unit: np.ndarray, outside: np.ndarray, normals: bool) -> None:
    """For ray i (``origins``, ``directions``: (N, 3) float64) and a triangle, the rows
    ``corners[i]`` (3,) of ``vertices`` (V, 3), with n = (b - a) x (c - a):

    - t[i] = n . (a - o) / n . d in float64 (inf where the ray runs along the plane, NaN for
      a degenerate triangle);
    - outside[i]: how far (metres, in the plane) the point o + t d lies beyond the triangle's
      edge lines, the largest of the three (0: on the triangle; NaN if t or n is unusable);
    - with ``normals``, unit[i] = n / |n| (NaN when |n| = 0)."""
    for i in range(origins.shape[0]):
        t[i], outside[i], nx, ny, nz, length = _plane_hit(
            origins[i, 0], origins[i, 1], origins[i, 2], directions[i, 0], directions[i, 1], directions[i, 2],
            vertices, corners[i, 0], corners[i, 1], corners[i, 2])
        if normals:
            _store_unit(unit, i, nx, ny, nz, length)


@numba.njit(cache=True, nogil=True, parallel=True)
def proposed_hits(origins: np.ndarray, directions: np.ndarray, proposed_t: np.ndarray, geometry: np.ndarray,
                  primitive: np.ndarray, face_start: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                  tol: float, t: np.ndarray, hit_geometry: np.ndarray, face: np.ndarray, outside: np.ndarray,
                  unit: np.ndarray, settled: np.ndarray, normals: bool) -> int:
    """:func:`plane_hits` of every ray on the triangle Embree proposed for it, face
    ``primitive[i]`` of geometry ``geometry[i]`` (row face_start[geometry[i]] + primitive[i] of
    ``faces``), where ``proposed_t[i]`` is finite: hit_geometry[i], face[i] = those two (else a
    miss: t inf, both -1, unit 0, settled); settled[i]: the plane hit lies on that triangle to
    within ``tol`` metres, at t >= 0. Returns the number of hits on degenerate triangles (no
    normal: unit NaN)."""
    degenerate = 0
    for i in numba.prange(origins.shape[0]):  # each ray on its own: the same answer on any thread count
        if not math.isfinite(proposed_t[i]):
            t[i], hit_geometry[i], face[i], outside[i], settled[i] = math.inf, -1, -1, math.nan, True
            if normals:
                unit[i, 0], unit[i, 1], unit[i, 2] = 0.0, 0.0, 0.0
            continue
        f = face_start[geometry[i]] + primitive[i]
        hit_geometry[i], face[i] = geometry[i], primitive[i]
        t[i], outside[i], nx, ny, nz, length = _plane_hit(
            origins[i, 0], origins[i, 1], origins[i, 2], directions[i, 0], directions[i, 1], directions[i, 2],
            vertices, faces[f, 0], faces[f, 1], faces[f, 2])
        settled[i] = outside[i] <= tol and t[i] >= 0.0
        if normals:
            _store_unit(unit, i, nx, ny, nz, length)
        if not length > 0.0:
            degenerate += 1
    return degenerate


@numba.njit(cache=True, nogil=True, parallel=True)
def float32_rays(origins: np.ndarray, directions: np.ndarray, rays: np.ndarray) -> None:
    """rays[i] = (origin, direction) rounded to float32 (Embree's input), as numpy's cast rounds."""
    for i in numba.prange(origins.shape[0]):
        for k in range(3):
            rays[i, k] = origins[i, k]
            rays[i, 3 + k] = directions[i, k]


@numba.njit(cache=True, nogil=True, parallel=True)
def farther_than(t: np.ndarray, directions: np.ndarray, reach: float) -> np.ndarray:
    """(N,) bool: ray i's hit (``t[i]`` in units of its direction's length; inf: none) lies at
    least ``reach`` metres from its origin."""
    out = np.empty(t.shape[0], dtype=np.bool_)
    r2 = reach * reach
    for i in numba.prange(t.shape[0]):
        d2 = (directions[i, 0] * directions[i, 0] + directions[i, 1] * directions[i, 1]) + directions[i, 2] * directions[i, 2]
        out[i] = t[i] * t[i] * d2 >= r2
    return out


@numba.njit(cache=True, nogil=True, parallel=True)
def take_rays(rows: np.ndarray, origins: np.ndarray, directions: np.ndarray, rays: np.ndarray):
    """(origins[rows], directions[rows], rays[rows]) as new arrays, in one pass."""
    m = rows.shape[0]
    o, d, r = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 6), dtype=np.float32)
    for j in numba.prange(m):
        i = rows[j]
        for k in range(3):
            o[j, k], d[j, k] = origins[i, k], directions[i, k]
        for k in range(6):
            r[j, k] = rays[i, k]
    return o, d, r


@numba.njit(cache=True, nogil=True)
def box_of(points: np.ndarray) -> np.ndarray:
    """(2, 3): the smallest and largest coordinates of ``points`` (N >= 1, 3), in one pass."""
    out = np.empty((2, 3))
    for k in range(3):
        out[0, k] = out[1, k] = points[0, k]
    for i in range(1, points.shape[0]):
        for k in range(3):
            v = points[i, k]
            if v < out[0, k]:
                out[0, k] = v
            elif v > out[1, k]:
                out[1, k] = v
    return out
