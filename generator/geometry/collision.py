"""Collision checks for a spherical camera of radius r moving along straight segments."""

from __future__ import annotations

import numpy as np

from .raycast import SceneGeometry


def position_is_free(geometry: SceneGeometry, position: np.ndarray, radius: float) -> bool:
    """True if a sphere of ``radius`` metres at ``position`` touches no triangle and is not
    inside a solid (closed) part."""
    p = np.asarray(position, dtype=np.float64).reshape(1, 3)
    if geometry.distance(p)[0] < radius:
        return False
    return not bool(geometry.inside_solid(p)[0])


def segment_is_free(
    geometry: SceneGeometry, start: np.ndarray, end: np.ndarray, radius: float, tolerance: float = 1e-3
) -> bool:
    """True if a sphere of ``radius`` swept from ``start`` to ``end`` touches no triangle and
    the end is not inside a solid.

    Exact up to ``tolerance`` metres: the distance to the scene is 1-Lipschitz, so between
    two samples at distances d_a, d_b, spaced by L, the distance stays above
    (d_a + d_b - L) / 2; intervals where that bound falls below ``radius`` are bisected
    until they are shorter than ``tolerance``.
    """
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    length = float(np.linalg.norm(b - a))
    if length > 0 and geometry.segments_blocked(a, b[None])[0]:
        return False
    n = max(2, int(np.ceil(length / max(radius, 1e-6))) + 1)
    t = np.linspace(0.0, 1.0, n)
    d = geometry.distance(a + t[:, None] * (b - a))
    if np.any(d < radius):
        return False
    lo_t, hi_t, lo_d, hi_d = t[:-1], t[1:], d[:-1], d[1:]
    while len(lo_t):
        span = (hi_t - lo_t) * length
        unsure = (lo_d + hi_d - span) / 2 < radius
        unsure &= span > tolerance
        lo_t, hi_t, lo_d, hi_d = lo_t[unsure], hi_t[unsure], lo_d[unsure], hi_d[unsure]
        if not len(lo_t):
            break
        mid_t = (lo_t + hi_t) / 2
        mid_d = geometry.distance(a + mid_t[:, None] * (b - a))
        if np.any(mid_d < radius):
            return False
        lo_t, hi_t, lo_d, hi_d = (
            np.concatenate([lo_t, mid_t]),
            np.concatenate([mid_t, hi_t]),
            np.concatenate([lo_d, mid_d]),
            np.concatenate([mid_d, hi_d]),
        )
    return not bool(geometry.inside_solid(b[None])[0])
