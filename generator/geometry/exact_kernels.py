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
- :func:`plane_hits`: where a ray meets the plane of the triangle it hit, and its normal.
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


@numba.njit(cache=True, nogil=True)
def plane_hits(origins: np.ndarray, directions: np.ndarray, vertices: np.ndarray, corners: np.ndarray,
               t: np.ndarray, unit: np.ndarray, normals: bool) -> None:
    """For ray i (``origins``, ``directions``: (N, 3) float64) and its triangle, the rows
    ``corners[i]`` (3,) of ``vertices`` (V, 3): t[i] = n . (a - o) / n . d with
    n = (b - a) x (c - a), in float64 (inf where the ray runs along the plane, NaN for a
    degenerate triangle), and with ``normals`` unit[i] = n / |n| (NaN when |n| = 0)."""
    for i in range(origins.shape[0]):
        ia, ib, ic = corners[i, 0], corners[i, 1], corners[i, 2]
        ax, ay, az = np.float64(vertices[ia, 0]), np.float64(vertices[ia, 1]), np.float64(vertices[ia, 2])
        e1x, e1y, e1z = vertices[ib, 0] - ax, vertices[ib, 1] - ay, vertices[ib, 2] - az
        e2x, e2y, e2z = vertices[ic, 0] - ax, vertices[ic, 1] - ay, vertices[ic, 2] - az
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        num = (nx * (ax - origins[i, 0]) + ny * (ay - origins[i, 1])) + nz * (az - origins[i, 2])
        den = (nx * directions[i, 0] + ny * directions[i, 1]) + nz * directions[i, 2]
        if den != 0.0:
            t[i] = num / den
        elif num != 0.0:
            t[i] = math.inf
        else:
            t[i] = math.nan
        if normals:
            length = math.sqrt((nx * nx + ny * ny) + nz * nz)
            if length > 0.0:
                unit[i, 0], unit[i, 1], unit[i, 2] = nx / length, ny / length, nz / length
            else:
                unit[i, 0], unit[i, 1], unit[i, 2] = math.nan, math.nan, math.nan
