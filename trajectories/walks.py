"""The paper's exploration baselines: random walk and modified random walk (section 4.2).

Both use exactly five actions: ``forward`` and ``left`` / ``right`` (moves of ``step``
metres along the camera's z / -x / +x axes) and ``turn_left`` / ``turn_right`` (turns of
``angle`` degrees about the world Z axis). A move that would collide leaves the pose
unchanged, as in the Simulator.
"""

from __future__ import annotations

import math

import numpy as np

from generator.geometry.camera import translated_along_axis, turned_about_world_z

from .base import MotionChecker, Trajectory, timestamps

ACTIONS = ("forward", "left", "right", "turn_left", "turn_right")


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


def _check(steps: int, step: float, angle: float) -> None:
    if not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"steps must be a positive integer, got {steps!r}")
    if not (step > 0 and math.isfinite(step)):
        raise ValueError(f"step must be a positive distance in metres, got {step!r}")
    if not (0 < angle < 360):
        raise ValueError(f"angle must be in (0, 360) degrees, got {angle!r}")


def random_walk(checker: MotionChecker, start: np.ndarray, steps: int, rng: np.random.Generator,
                step: float = 1.0, angle: float = 15.0, fps: float = 10.0) -> Trajectory:
    """``steps`` actions drawn uniformly from the five; returns steps + 1 poses (start first)."""
    _check(steps, step, angle)
    poses, actions = [np.array(start, dtype=np.float64)], []
    for _ in range(steps):
        action = ACTIONS[int(rng.integers(len(ACTIONS)))]
        pose, _ = _act(checker, poses[-1], action, step, angle)
        poses.append(pose)
        actions.append(action)
    return Trajectory(np.stack(poses), timestamps(len(poses), fps), "random_walk", actions,
                      {"step_m": step, "angle_deg": angle, "fps": fps})


def modified_random_walk(checker: MotionChecker, start: np.ndarray, steps: int, rng: np.random.Generator,
                         step: float = 1.0, angle: float = 15.0, fps: float = 10.0) -> Trajectory:
    """Go forward until the next forward move would collide, then turn (in ``angle``
    steps, one action each) to a randomly chosen heading whose forward move is free."""
    _check(steps, step, angle)
    poses, actions = [np.array(start, dtype=np.float64)], []
    plan: list[str] = []
    while len(actions) < steps:
        pose = poses[-1]
        if not plan:
            ahead = apply_action(pose, "forward", step, angle)
            if checker.can_move(pose[:3, 3], ahead[:3, 3]):
                plan = ["forward"]
            else:
                direction = "turn_left" if rng.random() < 0.5 else "turn_right"
                n_max = max(1, int(round(360 / angle)) - 1)
                free = []
                for k in range(1, n_max + 1):
                    turned = pose
                    for _ in range(k):
                        turned = apply_action(turned, direction, step, angle)
                    if checker.can_move(turned[:3, 3], apply_action(turned, "forward", step, angle)[:3, 3]):
                        free.append(k)
                k = int(rng.choice(free)) if free else 1  # boxed in: keep turning
                plan = [direction] * k
        action = plan.pop(0)
        new, _ = _act(checker, pose, action, step, angle)
        poses.append(new)
        actions.append(action)
    return Trajectory(np.stack(poses), timestamps(len(poses), fps), "modified_random_walk", actions,
                      {"step_m": step, "angle_deg": angle, "fps": fps})
