"""A smooth fly-through: a Catmull-Rom spline through random free waypoints, flown at
constant speed, looking along the path and slightly down (video-like sequences)."""

from __future__ import annotations

import math

import numpy as np

from generator.checks import check_integer, check_number
from generator.geometry import portable_math
from generator.geometry.camera import heading_pose

from . import checks
from .base import MotionChecker, Trajectory, TrajectoryError, timestamps
from .kinds import FlightSite, register_kind


def _catmull_rom(points: np.ndarray, samples_per_segment: int) -> np.ndarray:
    p = np.vstack([points[:1], points, points[-1:]])
    t = np.linspace(0, 1, samples_per_segment, endpoint=False)[:, None]
    out = []
    for k in range(1, len(p) - 2):
        p0, p1, p2, p3 = p[k - 1], p[k], p[k + 1], p[k + 2]
        out.append(0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * (t * t) + (-p0 + 3 * p1 - 3 * p2 + p3) * (t * t * t)))
    out.append(points[-1:])
    return np.concatenate(out)


def spline_flythrough(checker: MotionChecker, bounds, frames: int, rng: np.random.Generator,
                      speed: float = 3.0, waypoints: int = 6, pitch_deg: float = -15.0, fps: float = 10.0,
                      attempts: int = 50) -> Trajectory:
    """``frames`` poses flown at ``speed`` m/s through ``waypoints`` random free points
    inside ``bounds`` ((xmin, ymin, zmin), (xmax, ymax, zmax)); retried until every pose
    lies in ``bounds`` (the curve overshoots its waypoints) and every leg between consecutive
    poses is collision-free."""
    lo, hi = checks.box("bounds", bounds, 3)
    checks.count("frames", frames, 2)
    checks.generator("rng", rng)
    check_number("speed", speed, 0.0, open_low=True)
    check_integer("waypoints", waypoints, 2, checks.MAX_WAYPOINTS)
    checks.pitch("pitch_deg", pitch_deg)
    checks.fps(fps)
    check_integer("attempts", attempts, 1, checks.MAX_ATTEMPTS)
    length = speed * (frames - 1) / fps
    spacing = length / waypoints * 0.5  # consecutive waypoints at least this far apart
    if spacing >= float(portable_math.vector_norm(hi - lo)):
        raise TrajectoryError(f"a fly-through of {length:.0f} m ({frames} frames at {speed:g} m/s) needs waypoints "
                              f"{spacing:.0f} m apart, more than the {portable_math.vector_norm(hi - lo):.0f} m diagonal of its "
                              "box: use fewer frames")
    pitch = math.radians(pitch_deg)
    for _ in range(attempts):
        pts, draws = [lo + rng.random(3) * (hi - lo)], 0
        while len(pts) < waypoints and draws < 10_000:
            cand, draws = lo + rng.random(3) * (hi - lo), draws + 1
            if checker.is_free(cand) and portable_math.vector_norm(cand - pts[-1]) > spacing:
                pts.append(cand)
        if len(pts) < waypoints or not checker.is_free(pts[0]):
            continue
        curve = _catmull_rom(np.array(pts), 50)
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])
        if cum[-1] < length:
            continue
        s = np.linspace(0.0, length, frames)
        pos = np.column_stack([np.interp(s, cum, curve[:, k]) for k in range(3)])
        if np.any((pos < lo) | (pos > hi)):  # the curve overshoots its waypoints: stay in the box
            continue
        if not all(checker.can_move(a, b) for a, b in zip(pos[:-1], pos[1:])):
            continue
        ahead = np.column_stack([np.interp(np.minimum(s + 1.0, cum[-1]), cum, curve[:, k]) for k in range(3)])
        d = ahead - pos
        d[-1] = d[-2] if frames > 1 else d[-1]
        yaw = portable_math.atan2(d[:, 1], d[:, 0])  # the same bits on every CPU
        poses = np.stack([heading_pose(p, y, pitch) for p, y in zip(pos, yaw)])
        return Trajectory(poses, timestamps(frames, fps), "spline", [""] * (frames - 1),
                          {"speed_m_s": speed, "waypoints": np.array(pts).tolist(), "pitch_deg": pitch_deg, "fps": fps})
    raise TrajectoryError(f"no collision-free fly-through of {length:.0f} m found in {attempts} attempts (the "
                          "curve through the waypoints was too short, left the box or was blocked): use fewer frames")


@register_kind("spline")
def fit_spline(site: FlightSite) -> Trajectory:
    """A fly-through of the spawn box between max(its floor, 2 m) and min(its top,
    max(its floor + 5 m, 0.2 x the site's size)), with the planner's defaults (3 m/s)."""
    lo, hi = site.lo, site.hi
    top = min(hi[2], max(lo[2] + 5.0, 0.2 * site.size))
    return spline_flythrough(site.checker, ((lo[0], lo[1], max(lo[2], 2.0)), (hi[0], hi[1], top)), site.frames,
                             site.rng, fps=site.fps)
