"""Up-front checks of the planners' parameters: each raises a one-line ValueError naming the
parameter, its valid range and the value given, before any planning work. Numbers and
integers go through :mod:`generator.checks` (``check_number``, ``check_integer``); this module
declares what is the planners' own: the limits that keep their loops bounded
(docs/trajectories.md states them), vectors, boxes, poses, generators, fps, pitch, counts."""

from __future__ import annotations

import numpy as np

from generator.checks import check_integer, check_number, fail
from generator.geometry.camera import validate_rigid

MAX_POSES = 1_000_000  # frames / steps + 1 of one trajectory (a Python loop per pose)
MAX_PASSES = 10_000  # lawnmower gaps between lines (MAX_PASSES + 1 lines): spacing >= box height / MAX_PASSES
MAX_WAYPOINTS = 1_000  # a fly-through's waypoints (at most 10,000 are drawn per attempt)
MAX_ATTEMPTS = 1_000  # fly-through re-draws (each up to 10,000 free-space queries)
MAX_DRAWS = 100_000  # modified random walk: heading draws in one blocked step (one move query each)


def vectors(name: str, value, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` with finite entries; else ValueError saying
    ``what`` it must be."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != shape or not np.all(np.isfinite(a)):
        fail(name, what, value)
    return a


def box(name: str, value, dims: int) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of ``value`` = (lo, hi), two finite ``dims``-vectors with lo < hi on every axis."""
    axes = "(x, y)" if dims == 2 else "(x, y, z)"
    what = f"(lo, hi), two finite {axes} points with lo < hi on every axis"
    lo, hi = vectors(name, value, (2, dims), what)
    if not np.all(lo < hi):
        fail(name, what, value)
    return lo, hi


def pose(name: str, value) -> np.ndarray:
    """``value`` as a float64 4x4 rigid world_from_camera; else ValueError."""
    try:
        return validate_rigid(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 4x4 rigid world_from_camera pose ({exc})") from None


def generator(name: str, value) -> np.random.Generator:
    """``value`` if it is a numpy random Generator; else ValueError."""
    if not isinstance(value, np.random.Generator):
        fail(name, "a numpy.random.Generator (numpy.random.default_rng(seed))", value)
    return value


def fps(value) -> float:
    """Frames per second: timestamps are index / fps."""
    return check_number("fps", value, 0.0, open_low=True)


def pitch(name: str, value) -> float:
    """Camera pitch in degrees (negative: down), -90 to 90."""
    return check_number(name, value, -90.0, 90.0, valid="a number of degrees in [-90, 90] (negative: down)")


def count(name: str, value, low: int) -> int:
    """A number of frames or steps, from ``low`` to MAX_POSES."""
    return check_integer(name, value, low, MAX_POSES)
