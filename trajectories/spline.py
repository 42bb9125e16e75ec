"""A smooth fly-through: a Catmull-Rom spline through random free waypoints, flown at
constant speed, looking along the path and slightly down (video-like sequences), or at a
target gliding between two points (a drone filming the site: the view turns and the scene
moves across it, so frames have parallax)."""

from __future__ import annotations

import math

import numpy as np

from generator.checks import check_integer, check_number
from generator.geometry import portable_math
from generator.geometry.camera import heading_pose

from . import checks
from .base import MotionChecker, Trajectory, TrajectoryError, timestamps
from .kinds import FlightSite, register_kind


SPEED = 4.0  # m/s: the batch job's fly-through
WAYPOINT_STEP = 8.0  # metres of flight per waypoint, at most, in the batch job's fly-through


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
                      attempts: int = 50, look_at=None, min_target_distance: float = 6.0) -> Trajectory:
    """``frames`` poses flown at ``speed`` m/s through ``waypoints`` random free points
    inside ``bounds`` ((xmin, ymin, zmin), (xmax, ymax, zmax)), the first anywhere, each next
    1.3 x the flight's length / (waypoints - 1) from the one before in a random direction (up
    to 30 degrees up or down), so the flight turns and climbs along all of them; retried until every pose
    lies in ``bounds`` (the curve overshoots its waypoints) and every leg between consecutive
    poses is collision-free.

    Without ``look_at`` the camera looks along the path, pitched ``pitch_deg``. With
    ``look_at`` ((2, 3): a start and an end target, world metres) it looks at the target
    moving from the first to the second in step with the distance flown, with zero roll;
    paths that come within ``min_target_distance`` metres (horizontally) of the target are
    retried (the view would whip round)."""
    lo, hi = checks.box("bounds", bounds, 3)
    checks.count("frames", frames, 2)
    checks.generator("rng", rng)
    check_number("speed", speed, 0.0, open_low=True)
    check_integer("waypoints", waypoints, 2, checks.MAX_WAYPOINTS)
    checks.pitch("pitch_deg", pitch_deg)
    checks.fps(fps)
    check_integer("attempts", attempts, 1, checks.MAX_ATTEMPTS)
    targets = None if look_at is None else checks.vectors("look_at", look_at, (2, 3), "two finite (x, y, z) targets")
    check_number("min_target_distance", min_target_distance, 0.0)
    length = speed * (frames - 1) / fps
    step = 1.3 * length / (waypoints - 1)  # consecutive waypoints this far apart: the curve is a bit longer than the flight
    if step >= float(portable_math.vector_norm(hi - lo)):
        raise TrajectoryError(f"a fly-through of {length:.0f} m ({frames} frames at {speed:g} m/s) through {waypoints} "
                              f"waypoints needs them {step:.0f} m apart, more than the "
                              f"{portable_math.vector_norm(hi - lo):.0f} m diagonal of its box: use fewer frames or more waypoints")
    pitch = math.radians(pitch_deg)
    # waypoints keep off the box's faces by up to 0.15 x the step (the curve overshoots them
    # by a fraction of a step), at most a quarter of the box on each axis
    margin = np.minimum(0.15 * step, 0.25 * (hi - lo))
    inner_lo, inner_hi = lo + margin, hi - margin
    for _ in range(attempts):
        pts, draws = [inner_lo + rng.random(3) * (inner_hi - inner_lo)], 0
        while len(pts) < waypoints and draws < 10_000:  # each a step in a random direction (up to 30 degrees up or down)
            draws += 1
            heading, climb = rng.uniform(-math.pi, math.pi), rng.uniform(-0.5, 0.5)
            (sh, ch), (sc, cc) = portable_math.sincos(heading), portable_math.sincos(climb)
            cand = pts[-1] + step * np.array([cc * ch, cc * sh, sc])
            if np.all((cand >= inner_lo) & (cand <= inner_hi)) and checker.can_move(pts[-1], cand):
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
        if targets is None:
            ahead = np.column_stack([np.interp(np.minimum(s + 1.0, cum[-1]), cum, curve[:, k]) for k in range(3)])
            d = ahead - pos
            d[-1] = d[-2] if frames > 1 else d[-1]
            yaw = portable_math.atan2(d[:, 1], d[:, 0])  # the same bits on every CPU
            pitches = np.full(frames, pitch)
        else:
            w = (s / length)[:, None]
            d = targets[0] * (1 - w) + targets[1] * w - pos
            flat = portable_math.hypot(d[:, 0], d[:, 1])
            if np.any(flat < min_target_distance):
                continue
            yaw, pitches = portable_math.atan2(d[:, 1], d[:, 0]), portable_math.atan2(d[:, 2], flat)
        poses = np.stack([heading_pose(p, y, a) for p, y, a in zip(pos, yaw, pitches)])
        params = {"speed_m_s": speed, "waypoints": np.array(pts).tolist(), "fps": fps}
        params |= {"pitch_deg": pitch_deg} if targets is None else {"look_at": targets.tolist()}
        return Trajectory(poses, timestamps(frames, fps), "spline", [""] * (frames - 1), params)
    raise TrajectoryError(f"no collision-free fly-through of {length:.0f} m found in {attempts} attempts (the "
                          "curve through the waypoints was too short, left the box or was blocked): use fewer frames")


@register_kind("spline")
def fit_spline(site: FlightSite) -> Trajectory:
    """A fly-through of the spawn box between max(its floor, 2 m) and min(its top,
    max(its floor + 5 m, 0.2 x the site's size)) at 4 m/s, filming the site: looking at a
    target that glides between two points drawn within 0.15 x the site's size of the box's
    centre, 1.5-6 m up, and never coming within 4 m of it horizontally; a waypoint for
    every 8 m of flight (6 at least)."""
    lo, hi = site.lo, site.hi
    top = min(hi[2], max(lo[2] + 5.0, 0.2 * site.size))
    reach = 0.15 * site.size
    targets = [[site.centre[0] + site.rng.uniform(-reach, reach), site.centre[1] + site.rng.uniform(-reach, reach),
                site.rng.uniform(1.5, 6.0)] for _ in range(2)]
    length = SPEED * (site.frames - 1) / site.fps
    return spline_flythrough(site.checker, ((lo[0], lo[1], max(lo[2], 2.0)), (hi[0], hi[1], top)), site.frames,
                             site.rng, speed=SPEED, waypoints=max(6, math.ceil(length / WAYPOINT_STEP) + 1),
                             fps=site.fps, look_at=targets, min_target_distance=4.0)
