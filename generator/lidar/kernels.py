"""The per-beam arithmetic of a sweep, compiled (numba; bpy-free).

Each kernel evaluates, element by element, the same float64 expression as the numpy code it
replaces in generator/lidar/scanner.py, in the same order (numba without ``fastmath``
neither reorders nor fuses multiply-adds: tests/test_visibility.py checks the compiled
code), so the sweep's bytes are the same on every CPU; one pass over the beams instead of
numpy's gathers of (N, 3) rows is what makes them fast.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True, parallel=True)
def posed_rays(directions: np.ndarray, firing: np.ndarray, poses: np.ndarray, origin: np.ndarray,
               direction: np.ndarray) -> None:
    """Beam i's world ray from the pose ``poses[firing[i]]`` (4x4 world_from_sensor at its firing
    time): origin[i] = that pose's translation, direction[i] = R directions[i], as
    ``rows_times(directions, R^T)`` computes it: (d0 R[k, 0] + d1 R[k, 1]) + d2 R[k, 2]."""
    for i in numba.prange(directions.shape[0]):
        g = firing[i]
        x0, x1, x2 = directions[i, 0], directions[i, 1], directions[i, 2]
        for k in range(3):
            direction[i, k] = (x0 * poses[g, k, 0] + x1 * poses[g, k, 1]) + x2 * poses[g, k, 2]
            origin[i, k] = poses[g, k, 3]


@numba.njit(cache=True, nogil=True, parallel=True)
def return_points(rows: np.ndarray, origin: np.ndarray, direction: np.ndarray, sensor_directions: np.ndarray,
                  measured: np.ndarray, exact: np.ndarray, to_sensor: np.ndarray, world: np.ndarray,
                  xyz: np.ndarray, frozen: np.ndarray, surface: np.ndarray) -> None:
    """For return j (beam rows[j], ranges ``measured[j]`` and ``exact[j]``): world[j] = o + m d
    (float64); xyz[j] = sensor_directions[i] m (float32, the sensor frame at the beam's time);
    frozen[j] and surface[j] (float32): o + m d and o + r d carried by the 4x4 ``to_sensor``
    as ``apply_affine`` computes it, ((p0 R[k, 0] + p1 R[k, 1]) + p2 R[k, 2]) + t[k] (the
    points of static surfaces; moving ones are redone by the caller)."""
    for j in numba.prange(rows.shape[0]):
        i = rows[j]
        m, r = measured[j], exact[j]
        o0, o1, o2 = origin[i, 0], origin[i, 1], origin[i, 2]
        d0, d1, d2 = direction[i, 0], direction[i, 1], direction[i, 2]
        w0, w1, w2 = o0 + m * d0, o1 + m * d1, o2 + m * d2
        s0, s1, s2 = o0 + r * d0, o1 + r * d1, o2 + r * d2
        world[j, 0], world[j, 1], world[j, 2] = w0, w1, w2
        for k in range(3):
            xyz[j, k] = sensor_directions[i, k] * m
            frozen[j, k] = ((w0 * to_sensor[k, 0] + w1 * to_sensor[k, 1]) + w2 * to_sensor[k, 2]) + to_sensor[k, 3]
            surface[j, k] = ((s0 * to_sensor[k, 0] + s1 * to_sensor[k, 1]) + s2 * to_sensor[k, 2]) + to_sensor[k, 3]


@numba.njit(cache=True, nogil=True)
def glass_hits(part: np.ndarray, face: np.ndarray, first_face: np.ndarray, transparent: np.ndarray) -> np.ndarray:
    """The beams (int64, in order) whose hit (``part[i]`` (-1: none), ``face[i]``) is a glass
    face: ``transparent[first_face[part] + face]``."""
    count = 0
    for i in range(part.shape[0]):
        if part[i] >= 0 and transparent[first_face[part[i]] + face[i]]:
            count += 1
    out = np.empty(count, dtype=np.int64)
    count = 0
    for i in range(part.shape[0]):
        if part[i] >= 0 and transparent[first_face[part[i]] + face[i]]:
            out[count] = i
            count += 1
    return out
