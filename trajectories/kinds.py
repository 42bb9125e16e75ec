"""Trajectory kinds: each registers, beside its planner, how it is fitted to a site.

``@register_kind("orbit")`` on a function ``fit(site) -> Trajectory`` makes ``orbit`` a kind
of ``python -m generator --trajectory``: the batch job builds one :class:`FlightSite` per
seed and kind and calls the kind's fit, which picks the planner's parameters from the site
(an orbit's radius from the site's size, a walk's start from the spawn pose...). A new kind
is one new file in ``trajectories/`` (found by scanning the package: generator/registry.py)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from generator.registry import Registry, origin

from .base import BoundedChecker, MotionChecker, Trajectory


@dataclass(frozen=True)
class FlightSite:
    """What a kind's fit sees of a site: ``checker`` (collisions: the Simulator), ``lo`` and
    ``hi`` (3,) the corners of the camera spawn box (the flyable space, world metres),
    ``start`` the 4x4 world_from_camera spawn pose, ``rng`` the kind's own random stream of
    the seed, ``frames`` poses to plan and ``fps`` (timestamps are index / fps)."""

    checker: MotionChecker
    lo: np.ndarray
    hi: np.ndarray
    start: np.ndarray
    rng: np.random.Generator
    frames: int
    fps: float

    @property
    def centre(self) -> np.ndarray:
        """(3,) the middle of the spawn box."""
        return (self.lo + self.hi) / 2

    @property
    def size(self) -> float:
        """The spawn box's larger horizontal side, metres."""
        return float(max(self.hi[0] - self.lo[0], self.hi[1] - self.lo[1]))

    def boxed_checker(self) -> BoundedChecker:
        """``checker`` that also refuses to leave the spawn box (for planners that would
        otherwise wander off the site's unbounded ground plane)."""
        return BoundedChecker(self.checker, self.lo, self.hi)


Fit = Callable[[FlightSite], Trajectory]
TRAJECTORY_KINDS: Registry[Fit] = Registry("trajectory kind", "trajectories")


def register_kind(name: str) -> Callable[[Fit], Fit]:
    """Decorator: ``@register_kind("zigzag")`` on ``fit(site: FlightSite) -> Trajectory``."""

    def wrap(fit: Fit) -> Fit:
        return TRAJECTORY_KINDS.add(name, fit, origin(fit))

    return wrap


def fit_kind(kind: str, site: FlightSite) -> Trajectory:
    """A trajectory of ``kind`` fitted to ``site``; ValueError (one line, listing the kinds) if
    no kind has that name."""
    return TRAJECTORY_KINDS.get(kind)(site)
