"""The shared argument checks (generator/checks.py): what passes, and the one-line message of
what does not (the argument, its valid values, the value given)."""

import fractions
import math

import numpy as np
import pytest

from generator.checks import check_integer, check_number, check_seed


@pytest.mark.parametrize("args,kwargs,message", [
    (("x", "3"), {}, "x must be a finite number, got '3'"),  # a numeric string is not a number
    (("x", True), {}, "x must be a finite number, got True"),
    (("x", np.bool_(False)), {}, "x must be a finite number, got np.False_"),
    (("x", np.array(2.0)), {}, "x must be a finite number, got array(2.)"),
    (("x", None), {}, "x must be a finite number, got None"),
    (("x", math.nan), {"finite": False}, "x must be a number (+-inf allowed), got nan"),
    (("x", math.inf), {}, "x must be a finite number, got inf"),
    (("x", -math.inf, 0), {}, "x must be a finite number >= 0, got -inf"),
    (("x", 0, 0), {"open_low": True}, "x must be a finite number > 0, got 0"),
    (("x", 0, 0), {"open_low": True, "finite": False}, "x must be a number > 0 (inf allowed), got 0"),
    (("x", -math.inf), {"high": 5, "finite": False, "open_high": True}, None),
    (("x", 5), {"high": 5, "open_high": True}, "x must be a finite number < 5, got 5"),
    (("x", 1.5, 0, 1), {}, "x must be a number in [0, 1], got 1.5"),
    (("x", 1, 0, 1), {"open_high": True}, "x must be a number in [0, 1), got 1"),
    (("x", 0), {"nonzero": True}, "x must be a finite number, not 0, got 0"),
    (("turns", 9, -4, 4), {"valid": "a turn count in [-4, 4]"}, "turns must be a turn count in [-4, 4], got 9"),
])
def test_bad_numbers_give_one_line_naming_the_argument_its_range_and_the_value(args, kwargs, message):
    if message is None:  # -inf with finite=False is inside (-inf, 5)
        assert check_number(*args, **kwargs) == -math.inf
        return
    with pytest.raises(ValueError) as info:
        check_number(*args, **kwargs)
    assert str(info.value) == message


def test_numbers_that_pass_come_back_as_floats():
    assert check_number("x", np.float32(2.5), 0, 3) == 2.5 and type(check_number("x", np.float32(2.5))) is float
    assert check_number("x", np.int64(7)) == 7.0 and check_number("x", fractions.Fraction(1, 4)) == 0.25
    assert check_number("x", 0, 0, 1) == 0.0 and check_number("x", 1, 0, 1) == 1.0  # closed ends are inside
    assert check_number("clip", math.inf, 0, open_low=True, finite=False) == math.inf
    assert check_number("x", -0.5, nonzero=True) == -0.5


@pytest.mark.parametrize("args,kwargs,message", [
    (("n", 2.0, 0), {}, "n must be an integer >= 0, got 2.0"),
    (("n", True, 0), {}, "n must be an integer >= 0, got True"),
    (("n", "3", 0), {}, "n must be an integer >= 0, got '3'"),
    (("n", 0, 1, 10_000), {}, "n must be an integer from 1 to 10,000, got 0"),
    (("n", 10_001, 1, 10_000), {}, "n must be an integer from 1 to 10,000, got 10001"),
    (("n", -1, 0), {"valid": "a count"}, "n must be a count, got -1"),
])
def test_bad_integers_give_one_line(args, kwargs, message):
    with pytest.raises(ValueError) as info:
        check_integer(*args, **kwargs)
    assert str(info.value) == message


def test_integers_and_seeds_that_pass():
    assert check_integer("n", np.uint8(5), 1, 5) == 5 and type(check_integer("n", np.int64(3), 0)) is int
    assert check_integer("n", 10**30, 0) == 10**30  # no upper end unless one is given
    assert check_seed("seed", np.int32(0)) == 0 and check_seed("seed", 2**63 - 1) == 2**63 - 1
    for bad in (-1, True, 1.0, "1", None, 2**63, 2**64):  # seeds are stored as signed 64-bit integers
        with pytest.raises(ValueError, match=r"^seed must be an integer from 0 to 9223372036854775807 \(2\*\*63-1\), got "):
            check_seed("seed", bad)
