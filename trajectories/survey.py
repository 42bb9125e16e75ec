"""UAV survey patterns for structure-from-motion: orbits and lawnmower passes, looking
obliquely at the site, raised until every leg is collision-free."""

from __future__ import annotations

import math

import numpy as np

from generator.checks import check_number
from generator.geometry import portable_math
from generator.geometry.camera import heading_pose, look_at

from . import checks
from .base import MotionChecker, Trajectory, TrajectoryError, timestamps
from .kinds import FlightSite, register_kind


def _clear(checker: MotionChecker, positions: np.ndarray) -> bool:
    if not checker.is_free(positions[0]):
        return False
    return all(checker.can_move(a, b) for a, b in zip(positions[:-1], positions[1:]))


def _raise_until_clear(checker, make, altitude: float, max_raise: float = 60.0, step: float = 5.0):
    """Call ``make(altitude)`` -> (positions, poses), raising the altitude until clear."""
    for extra in np.arange(0.0, max_raise + 1e-9, step):
        positions, poses = make(altitude + extra)
        if _clear(checker, positions):
            return poses, altitude + extra
    raise TrajectoryError(f"no collision-free survey up to {altitude + max_raise:.0f} m altitude")


def orbit(checker: MotionChecker, center, radius: float, altitude: float, frames: int,
          look_at_height: float = 0.0, turns: float = 1.0, fps: float = 10.0, start_angle: float = 0.0) -> Trajectory:
    """``frames`` poses on a circle of ``radius`` metres at ``altitude`` metres around
    ``center`` (x, y), each looking at the centre at ``look_at_height``."""
    c = checks.vectors("center", center, (2,), "(x, y), two finite numbers of metres")
    check_number("radius", radius, 0.0, open_low=True)
    check_number("altitude", altitude)
    checks.count("frames", frames, 2)
    check_number("look_at_height", look_at_height)
    check_number("turns", turns, -frames / 2, frames / 2, nonzero=True,
                 valid=f"a nonzero number with |turns| <= frames / 2 = {frames / 2:g} (negative: clockwise)")
    checks.fps(fps)
    check_number("start_angle", start_angle)
    a = start_angle + 2 * math.pi * turns * np.arange(frames) / frames

    def make(alt):
        sin_a, cos_a = portable_math.sincos(a)  # the same bits on every CPU
        pos = np.column_stack([c[0] + radius * cos_a, c[1] + radius * sin_a, np.full(frames, alt)])
        return pos, np.stack([look_at(p, (c[0], c[1], look_at_height)) for p in pos])

    poses, alt = _raise_until_clear(checker, make, altitude)
    return Trajectory(poses, timestamps(frames, fps), "orbit", [""] * (frames - 1),
                      {"center": c.tolist(), "radius_m": radius, "altitude_m": alt, "turns": turns, "fps": fps})


@register_kind("orbit")
def fit_orbit(site: FlightSite) -> Trajectory:
    """One turn around the spawn box's centre at 0.45 x the site's size, at max(0.3 x size,
    15 m) altitude (raised until clear), looking at the point 2 m above the centre."""
    size = site.size
    return orbit(site.checker, site.centre[:2], 0.45 * size, max(0.3 * size, 15.0), site.frames, look_at_height=2.0,
                 fps=site.fps)


def lawnmower(checker: MotionChecker, bounds, altitude: float, frames: int, spacing: float,
              pitch_deg: float = -45.0, fps: float = 10.0) -> Trajectory:
    """Back-and-forth passes along x over ``bounds`` ((xmin, ymin), (xmax, ymax)), lines
    ``spacing`` metres apart, at ``altitude``, camera pitched ``pitch_deg`` (negative:
    down) along the direction of flight; ``frames`` poses evenly spaced along the path."""
    lo, hi = checks.box("bounds", bounds, 2)
    check_number("altitude", altitude)
    checks.count("frames", frames, 2)
    least = float(hi[1] - lo[1]) / checks.MAX_PASSES
    check_number("spacing", spacing, least, valid=f"a number of metres >= {least:g} (at most "
                 f"{checks.MAX_PASSES:,} gaps between passes across the {hi[1] - lo[1]:g} m of the bounds in y)")
    checks.pitch("pitch_deg", pitch_deg)
    checks.fps(fps)
    (x0, y0), (x1, y1) = bounds
    ys = np.arange(y0, y1 + 1e-9, spacing)
    corners = []
    for k, y in enumerate(ys):
        corners += [(x0, y), (x1, y)] if k % 2 == 0 else [(x1, y), (x0, y)]
    corners = np.array(corners)
    seg = np.diff(corners, axis=0)
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(seg, axis=1))])
    s = np.linspace(0.0, cum[-1], frames)
    idx = np.minimum(np.searchsorted(cum, s, side="right") - 1, len(seg) - 1)
    frac = (s - cum[idx]) / np.maximum(cum[idx + 1] - cum[idx], 1e-12)
    xy = corners[idx] + frac[:, None] * seg[idx]
    yaw = portable_math.atan2(seg[idx, 1], seg[idx, 0])
    pitch = math.radians(pitch_deg)

    def make(alt):
        pos = np.column_stack([xy, np.full(frames, alt)])
        return pos, np.stack([heading_pose(p, y, pitch) for p, y in zip(pos, yaw)])

    poses, alt = _raise_until_clear(checker, make, altitude)
    return Trajectory(poses, timestamps(frames, fps), "lawnmower", [""] * (frames - 1),
                      {"bounds": [[x0, y0], [x1, y1]], "spacing_m": spacing, "altitude_m": alt, "pitch_deg": pitch_deg, "fps": fps})


@register_kind("lawnmower")
def fit_lawnmower(site: FlightSite) -> Trajectory:
    """Passes over the spawn box less a margin of 0.1 x the site's size on every side, lines
    size / 4 apart, at max(0.25 x size, 15 m) altitude (raised until clear)."""
    lo, hi, size = site.lo, site.hi, site.size
    margin = 0.1 * size
    return lawnmower(site.checker, ((lo[0] + margin, lo[1] + margin), (hi[0] - margin, hi[1] - margin)),
                     max(0.25 * size, 15.0), site.frames, spacing=size / 4, fps=site.fps)
