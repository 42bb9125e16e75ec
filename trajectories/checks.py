"""Up-front checks of the planners' parameters: each raises a one-line ValueError naming the
parameter, its valid range and the value given, before any planning work. The limits that
keep a planner's loops bounded are declared here (docs/trajectories.md states them)."""

from __future__ import annotations

import math
import numbers

import numpy as np

MAX_POSES = 1_000_000  # frames / steps + 1 of one trajectory (a Python loop per pose)
MAX_PASSES = 10_000  # lawnmower lines across its box: spacing >= box height / MAX_PASSES
MAX_WAYPOINTS = 1_000  # a fly-through's waypoints (at most 10,000 are drawn per attempt)
MAX_ATTEMPTS = 1_000  # fly-through re-draws (each up to 10,000 free-space queries)
MAX_DRAWS = 100_000  # modified random walk: heading draws in one blocked step (one move query each)


def _fail(name: str, valid: str, value) -> None:
    raise ValueError(f"{name} must be {valid}, got {value!r}")


def number(name: str, value, low: float = -math.inf, high: float = math.inf, *, open_low: bool = False,
           open_high: bool = False, nonzero: bool = False, valid: str | None = None) -> float:
    """``value`` as a float if it is a finite real number in [low, high] (``open_low`` /
    ``open_high``: that end excluded; ``nonzero``: 0 excluded); else ValueError (``valid``
    replaces the range's words)."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)
    if ok:
        v = float(value)
        ok = (v > low if open_low else v >= low) and (v < high if open_high else v <= high) and not (nonzero and v == 0)
    if not ok:
        _fail(name, valid or _range_words(low, high, open_low, open_high), value)
    return v


def _range_words(low, high, open_low, open_high) -> str:
    if math.isinf(low) and math.isinf(high):
        return "a finite number"
    if math.isinf(high):
        return f"a finite number {'>' if open_low else '>='} {low:g}"
    if math.isinf(low):
        return f"a finite number {'<' if open_high else '<='} {high:g}"
    return f"a number in {'(' if open_low else '['}{low:g}, {high:g}{')' if open_high else ']'}"


def integer(name: str, value, low: int, high: int) -> int:
    """``value`` if it is an integer (not a bool) from ``low`` to ``high``; else ValueError."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not low <= value <= high:
        _fail(name, f"an integer from {low:,} to {high:,}", value)
    return int(value)


def vectors(name: str, value, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` with finite entries; else ValueError saying
    ``what`` it must be."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != shape or not np.all(np.isfinite(a)):
        _fail(name, what, value)
    return a


def box(name: str, value, dims: int) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of ``value`` = (lo, hi), two finite ``dims``-vectors with lo < hi on every axis."""
    axes = "(x, y)" if dims == 2 else "(x, y, z)"
    what = f"(lo, hi), two finite {axes} points with lo < hi on every axis"
    lo, hi = vectors(name, value, (2, dims), what)
    if not np.all(lo < hi):
        _fail(name, what, value)
    return lo, hi


def pose(name: str, value) -> np.ndarray:
    """``value`` as a float64 4x4 rigid world_from_camera; else ValueError."""
    from generator.geometry.camera import validate_rigid

    try:
        return validate_rigid(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 4x4 rigid world_from_camera pose ({exc})") from None


def generator(name: str, value) -> np.random.Generator:
    """``value`` if it is a numpy random Generator; else ValueError."""
    if not isinstance(value, np.random.Generator):
        _fail(name, "a numpy.random.Generator (numpy.random.default_rng(seed))", value)
    return value


def fps(value) -> float:
    """Frames per second: timestamps are index / fps."""
    return number("fps", value, 0.0, open_low=True)


def pitch(name: str, value) -> float:
    """Camera pitch in degrees (negative: down), -90 to 90."""
    return number(name, value, -90.0, 90.0, valid="a number of degrees in [-90, 90] (negative: down)")


def count(name: str, value, low: int) -> int:
    """A number of frames or steps, from ``low`` to MAX_POSES."""
    return integer(name, value, low, MAX_POSES)
