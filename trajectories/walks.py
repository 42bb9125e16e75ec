"""The paper's exploration baselines: random walk and modified random walk (section 4.2),
as its evaluation code runs them.

The random walk draws one of five actions per step: ``forward`` and ``left`` / ``right``
(moves of ``step`` metres along the camera's z / -x / +x axes) and ``turn_left`` /
``turn_right`` (turns of ``angle`` degrees about the world Z axis). The modified random
walk moves forward every step and, when blocked, draws random headings inside that step
until the move is free. A move that would collide leaves the pose unchanged, as in the
Simulator.
"""

from __future__ import annotations

import math

import numpy as np

from generator.checks import check_integer, check_number, items
from generator.geometry.camera import levelled, translated_along_axis, turned_about_world_z

from . import checks
from .base import MotionChecker, Trajectory, timestamps
from .kinds import FlightSite, register_kind

ACTIONS = ("forward", "left", "right", "turn_left", "turn_right")
# the five actions of the paper's evaluation code as written: its 'right' calls
# move_camera_right(-3), a second left (kept to measure what that changes: docs/results.md)
PAPER_CODE_ACTIONS = ("forward", "left", "left", "turn_right", "turn_left")


def apply_action(pose: np.ndarray, action: str, step: float, angle_deg: float) -> np.ndarray:
    """The pose after ``action`` (collisions not checked)."""
    if action == "forward":
        return translated_along_axis(pose, 2, step)
    if action == "left":
        return translated_along_axis(pose, 0, -step)
    if action == "right":
        return translated_along_axis(pose, 0, step)
    if action in ("turn_left", "turn_right"):
        a = math.radians(angle_deg)
        return turned_about_world_z(pose, -a if action == "turn_left" else a)
    raise ValueError(f"unknown action {action!r}; actions are {', '.join(ACTIONS)}")


def _act(checker: MotionChecker, pose: np.ndarray, action: str, step: float, angle: float) -> tuple[np.ndarray, bool]:
    """(new pose, collided)."""
    new = apply_action(pose, action, step, angle)
    if action in ("forward", "left", "right") and not checker.can_move(pose[:3, 3], new[:3, 3]):
        return pose, True
    return new, False


def _check(start, steps: int, rng, step: float, angle: float, fps: float) -> None:
    """The parameters the two walks share (ValueError naming the first bad one)."""
    checks.pose("start", start)
    checks.count("steps", steps, 1)
    checks.generator("rng", rng)
    check_number("step", step, 0.0, open_low=True, valid="a distance in metres > 0")
    check_number("angle", angle, 0.0, 360.0, open_low=True, open_high=True, valid="a number of degrees in (0, 360)")
    checks.fps(fps)


def random_walk(checker: MotionChecker, start: np.ndarray, steps: int, rng: np.random.Generator,
                step: float = 3.0, angle: float = 22.5, fps: float = 10.0,
                actions: tuple[str, ...] = ACTIONS) -> Trajectory:
    """``steps`` actions drawn uniformly from ``actions`` (default: the five); returns
    steps + 1 poses (start first). Defaults are the paper's code: 3 m moves, 22.5 degree turns."""
    _check(start, steps, rng, step, angle, fps)
    choices = items(actions) or ()
    if not choices or any(a not in ACTIONS for a in choices):
        raise ValueError(f"actions must be a non-empty list drawn from {', '.join(ACTIONS)}, got {actions!r}")
    poses, taken = [np.array(start, dtype=np.float64)], []
    for _ in range(steps):
        action = choices[int(rng.integers(len(choices)))]
        pose, _ = _act(checker, poses[-1], action, step, angle)
        poses.append(pose)
        taken.append(action)
    params = {"step_m": step, "angle_deg": angle, "fps": fps} | ({} if choices == ACTIONS else {"actions": list(choices)})
    return Trajectory(np.stack(poses), timestamps(len(poses), fps), "random_walk", taken, params)


MODIFIED_WALK_ACTIONS = ("forward", "turn_forward", "stuck")


def modified_random_walk(checker: MotionChecker, start: np.ndarray, steps: int, rng: np.random.Generator,
                         step: float = 3.0, angle: float = 22.5, fps: float = 10.0,
                         max_draws: int = 1000) -> Trajectory:
    """The paper's modified random walk: every step is one forward move of ``step`` metres.

    When the forward move is blocked, the camera turns by an angle drawn uniformly in
    [-180, 180) degrees about the world Z axis and tries again, as often as needed, all
    inside the same step (the paper's evaluation code). Each step's action is ``forward``
    (the move was free), ``turn_forward`` (headings were drawn, then the move was made) or
    ``stuck`` (no free heading in ``max_draws`` draws, where the paper's code would loop
    forever: the camera keeps its position and its last drawn heading). ``angle`` is not
    used (the walks share one signature); returns steps + 1 poses (start first).
    """
    _check(start, steps, rng, step, angle, fps)
    check_integer("max_draws", max_draws, 1, checks.MAX_DRAWS)
    poses, actions, draws = [np.array(start, dtype=np.float64)], [], []
    for _ in range(steps):
        pose, n = poses[-1], 0
        new, blocked = _act(checker, pose, "forward", step, angle)
        while blocked and n < max_draws:
            pose = turned_about_world_z(pose, math.radians(rng.uniform(-180.0, 180.0)))
            n += 1
            new, blocked = _act(checker, pose, "forward", step, angle)
        poses.append(new)
        actions.append("stuck" if blocked else ("turn_forward" if n else "forward"))
        draws.append(n)
    return Trajectory(np.stack(poses), timestamps(len(poses), fps), "modified_random_walk", actions,
                      {"step_m": step, "fps": fps, "max_draws": int(max_draws), "heading_draws": draws})


def _fit_walk(walk, site: FlightSite) -> Trajectory:
    """``walk`` from the levelled spawn pose ('forward' is horizontal), kept inside the spawn
    box, one step a frame: 1 m moves and 15 degree turns (the planners' defaults, 3 m and
    22.5 degrees, are the paper's exploration steps)."""
    return walk(site.boxed_checker(), levelled(site.start), site.frames - 1, site.rng, step=1.0, angle=15.0,
                fps=site.fps)


@register_kind("random_walk")
def fit_random_walk(site: FlightSite) -> Trajectory:
    return _fit_walk(random_walk, site)


@register_kind("modified_random_walk")
def fit_modified_random_walk(site: FlightSite) -> Trajectory:
    return _fit_walk(modified_random_walk, site)
