"""Collision checks for a spherical camera of radius r moving along straight segments."""

from __future__ import annotations

import numpy as np

from ..checks import MAX_COORDINATE
from .portable_math import vector_norm
from .raycast import SceneGeometry

_MAX_SAMPLES = 100_000  # first pass of a sweep; the bisection below keeps the test exact
_LONG = 1000.0  # metres: longer moves are first clipped to the scene's bounds


def checked_position(position, name: str = "position") -> np.ndarray:
    """(3,) float64; ValueError for anything but three finite numbers within MAX_COORDINATE."""
    try:
        p = np.asarray(position, dtype=np.float64).reshape(3)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be three numbers (x, y, z) in metres, got {position!r}") from None
    if not np.isfinite(p).all() or np.abs(p).max() > MAX_COORDINATE:
        raise ValueError(f"{name} must be finite metres within {MAX_COORDINATE:.0e} of the origin, got {p.tolist()}")
    return p


def position_is_free(geometry: SceneGeometry, position: np.ndarray, radius: float) -> bool:
    """True if a sphere of ``radius`` metres at ``position`` touches no triangle and is not
    inside a solid (closed) part. A non-finite position raises ValueError."""
    p = checked_position(position).reshape(1, 3)
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
    a, b = checked_position(start, "start"), checked_position(end, "end")
    length = float(vector_norm(b - a))  # not np.linalg.norm: BLAS, whose rounding depends on the CPU
    t0, t1 = 0.0, 1.0
    if length > _LONG:
        # far from every part's bounds (grown by the radius) the sphere touches nothing: test
        # only the stretch of the segment inside them, so the work (and the float32 precision
        # of the ray test) is bounded by the scene's size, not by the length of the move
        window = _clip_to_box(a, b, geometry.world_bounds(), radius + tolerance)
        if window is None:
            return not bool(geometry.inside_solid(b[None])[0])
        t0, t1 = window
    p0, p1 = a + t0 * (b - a), a + t1 * (b - a)
    if length > 0 and np.any(p1 != p0) and geometry.segments_blocked(p0, p1[None])[0]:
        return False
    n = min(_MAX_SAMPLES, max(2, int(np.ceil((t1 - t0) * length / max(radius, 1e-6))) + 1))
    t = np.linspace(t0, t1, n)
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


def move_is_allowed(geometry: SceneGeometry, start: np.ndarray, end: np.ndarray, radius: float) -> bool:
    """A camera move: :func:`segment_is_free`, except that staying in place (a turn) is always
    allowed, and a sphere that already touches geometry at ``start`` (a scene's own camera
    placed too close to a surface) may leave it: to a free ``end``, along a segment that
    crosses no surface (the paper's ray test)."""
    a, b = checked_position(start, "start"), checked_position(end, "end")
    if np.array_equal(a, b) or segment_is_free(geometry, a, b, radius):
        return True
    return (not position_is_free(geometry, a, radius) and position_is_free(geometry, b, radius)
            and not geometry.segments_blocked(a, b[None])[0])


def _clip_to_box(a: np.ndarray, b: np.ndarray, bounds: np.ndarray, margin: float) -> tuple[float, float] | None:
    """Parameter range [t0, t1] of the segment a + t (b - a), t in [0, 1], inside the box
    around all ``bounds`` (P, 2, 3) grown by ``margin``; None if it misses the box."""
    if not len(bounds):
        return None
    lo, hi = bounds[:, 0].min(axis=0) - margin, bounds[:, 1].max(axis=0) + margin
    d = b - a
    t0, t1 = 0.0, 1.0
    for k in range(3):
        if d[k] == 0:
            if not lo[k] <= a[k] <= hi[k]:
                return None
            continue
        u, v = sorted(((lo[k] - a[k]) / d[k], (hi[k] - a[k]) / d[k]))
        t0, t1 = max(t0, u), min(t1, v)
    return (t0, t1) if t0 <= t1 else None
