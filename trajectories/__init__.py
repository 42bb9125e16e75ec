"""Camera path planners (numpy only; no bpy). Every planner asks a :class:`MotionChecker`
(``can_move``, ``is_free``; the Simulator implements both) and returns a
:class:`Trajectory` of OpenCV world_from_camera poses with timestamps.

Each kind of ``python -m generator --trajectory`` registers, beside its planner, how it is
fitted to a site (``@register_kind``: trajectories/kinds.py); every module of this package
is imported here, so a new kind is one new file. :data:`KINDS` lists them (name order)."""

from .base import BoundedChecker, MotionChecker, Trajectory, TrajectoryError
from .kinds import TRAJECTORY_KINDS, FlightSite, fit_kind, register_kind
from .spline import spline_flythrough
from .survey import lawnmower, orbit
from .walks import ACTIONS, PAPER_CODE_ACTIONS, apply_action, modified_random_walk, random_walk

KINDS = TRAJECTORY_KINDS.names()  # imports every module of the package, registering its kinds

__all__ = ["ACTIONS", "KINDS", "PAPER_CODE_ACTIONS", "TRAJECTORY_KINDS", "BoundedChecker", "FlightSite",
           "MotionChecker", "Trajectory", "TrajectoryError", "apply_action", "fit_kind", "lawnmower",
           "modified_random_walk", "orbit", "random_walk", "register_kind", "spline_flythrough"]
