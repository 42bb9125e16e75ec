"""Argument checks shared by the Simulator and the environments (bpy-free): one-line
ValueErrors that name the argument."""

from __future__ import annotations

import math
import numbers


def check_number(name: str, value, low=None, high=None, low_open: bool = False) -> float:
    """``value`` as a float, refusing booleans, non-numbers, NaN and values outside
    [low, high] (or (low, high] with ``low_open``)."""
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if math.isnan(v):
        raise ValueError(f"{name} must be a number, got NaN")
    if low is not None and (v <= low if low_open else v < low):
        raise ValueError(f"{name} must be {'>' if low_open else '>='} {low}, got {value!r}")
    if high is not None and v > high:
        raise ValueError(f"{name} must be <= {high}, got {value!r}")
    return v


def check_seed(name: str, value) -> int:
    """``value`` as an int, refusing booleans, non-integers (floats included) and negatives."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    return int(value)
