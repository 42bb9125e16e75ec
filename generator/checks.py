"""Argument checks shared by the Simulator, the environments and the trajectory planners
(bpy-free): each raises a one-line ValueError naming the argument, its valid values and the
value given.

Numbers must be real numbers (Python or numpy; not bools, strings or arrays), integers must be
integral (Python or numpy; not bools or floats). A number is finite unless the caller says
``finite=False`` (a clip distance, where ``math.inf`` means no limit); NaN never passes.
"""

from __future__ import annotations

import math
import numbers
from typing import NoReturn

import numpy as np


def items(value) -> tuple | None:
    """The items of a list-like ``value`` (list, tuple, array, generator) as a tuple; None for
    what is not one: a string or bytes (a single name, not a list of letters), a number,
    None, a path, a 0-d array."""
    if isinstance(value, (str, bytes)):
        return None
    try:
        return tuple(value)
    except TypeError:
        return None


def fail(name: str, valid: str, value) -> NoReturn:
    """Raise the one-line ValueError: '``name`` must be ``valid``, got ``value``'."""
    raise ValueError(f"{name} must be {valid}, got {value!r}")


def check_number(name: str, value, low: float = -math.inf, high: float = math.inf, *, open_low: bool = False,
                 open_high: bool = False, nonzero: bool = False, finite: bool = True,
                 valid: str | None = None) -> float:
    """``value`` as a float if it is a real number in [low, high] (``open_low`` /
    ``open_high``: that end excluded; ``nonzero``: 0 excluded; ``finite=False``: +-inf allowed
    where the range holds it); else ValueError (``valid`` replaces the range's words)."""
    v = float(value) if isinstance(value, numbers.Real) and not isinstance(value, bool) else math.nan
    ok = (not math.isnan(v) and (math.isfinite(v) or not finite)
          and (v > low if open_low else v >= low) and (v < high if open_high else v <= high)
          and not (nonzero and v == 0))
    if not ok:
        fail(name, valid or _range_words(low, high, open_low, open_high, nonzero, finite), value)
    return v


def _range_words(low, high, open_low, open_high, nonzero, finite) -> str:
    kind = "a finite number" if finite else "a number"
    if math.isinf(low) and math.isinf(high):
        words = kind
    elif math.isinf(high):
        words = f"{kind} {'>' if open_low else '>='} {low:g}"
    elif math.isinf(low):
        words = f"{kind} {'<' if open_high else '<='} {high:g}"
    else:
        words = f"a number in {'(' if open_low else '['}{low:g}, {high:g}{')' if open_high else ']'}"
    if not finite and (math.isinf(low) or math.isinf(high)):
        words += f" ({'+-' if math.isinf(low) and math.isinf(high) else '-' if math.isinf(low) else ''}inf allowed)"
    return words + (", not 0" if nonzero else "")


def check_integer(name: str, value, low: int, high: int | None = None, *, valid: str | None = None) -> int:
    """``value`` as an int if it is an integer (not a bool) from ``low`` to ``high`` (None: no
    upper end); else ValueError (``valid`` replaces the range's words)."""
    if (isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low
            or (high is not None and value > high)):
        fail(name, valid or (f"an integer >= {low:,}" if high is None else f"an integer from {low:,} to {high:,}"),
             value)
    return int(value)


MAX_FRAME = 1_048_574  # Blender's frame limit (MAXFRAME), either sign
MAX_COORDINATE = 1e10  # metres; camera positions farther from the origin are refused


class Checked:
    """A settable attribute that runs ``check(value)`` (a one-line ValueError) on every
    assignment, so that ``obj.name = bad`` fails where the constructor would, not later."""

    def __init__(self, check):
        self.check = check

    def __set_name__(self, owner, name: str) -> None:
        self.slot = "_checked_" + name

    def __get__(self, obj, objtype=None):
        return self if obj is None else getattr(obj, self.slot)

    def __set__(self, obj, value) -> None:
        setattr(obj, self.slot, self.check(value))


def check_flag(name: str, value) -> bool:
    """``value`` as a bool if it is one (Python or numpy); else ValueError (no truthy strings)."""
    if not isinstance(value, (bool, np.bool_)):
        fail(name, "True or False", value)
    return bool(value)


MAX_SEED = 2**63 - 1  # seeds are stored as signed 64-bit integers (HDF5 attributes, numpy)


def check_seed(name: str, value) -> int:
    """A random seed: an integer from 0 to MAX_SEED (numpy integers too; bools and floats refused)."""
    return check_integer(name, value, 0, MAX_SEED, valid=f"an integer from 0 to {MAX_SEED} (2**63-1)")
