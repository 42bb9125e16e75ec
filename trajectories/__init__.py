"""Camera path planners (numpy only; no bpy). Every planner asks a :class:`MotionChecker`
(``can_move``, ``is_free``; the Simulator implements both) and returns a
:class:`Trajectory` of OpenCV world_from_camera poses with timestamps."""

from .base import BoundedChecker, MotionChecker, Trajectory, TrajectoryError
from .spline import spline_flythrough
from .survey import lawnmower, orbit
from .walks import ACTIONS, PAPER_CODE_ACTIONS, apply_action, modified_random_walk, random_walk

KINDS = ("random_walk", "modified_random_walk", "orbit", "lawnmower", "spline")

__all__ = ["ACTIONS", "KINDS", "PAPER_CODE_ACTIONS", "BoundedChecker", "MotionChecker", "Trajectory", "TrajectoryError", "apply_action", "lawnmower",
           "modified_random_walk", "orbit", "random_walk", "spline_flythrough"]
