"""Reference sine, cosine and arctangent in exact integer arithmetic (fixed point, 2**-240)
for checking generator/geometry/portable_math.py: every float64 is an exact binary fraction,
so its sine is computed to ~1e-70 here and compared in units in the last place."""

from __future__ import annotations

import math
from fractions import Fraction

BITS = 240
ONE = 1 << BITS


def _atan_inverse(n: int) -> int:
    """atan(1/n) in fixed point (Taylor series, n >= 2)."""
    total, term, k, n2 = 0, ONE // n, 0, n * n
    while term:
        total += term // (2 * k + 1) if k % 2 == 0 else -(term // (2 * k + 1))
        term //= n2
        k += 1
    return total


PI = 4 * (4 * _atan_inverse(5) - _atan_inverse(239))  # Machin's formula


def fixed(x: float) -> int:
    """The float x in fixed point (exact when x is a multiple of 2**-240)."""
    f = Fraction(x)
    return f.numerator * ONE // f.denominator


def _sin_cos_small(r: int) -> tuple[int, int]:
    """sin r, cos r for |r| <= 1 (fixed point) by Taylor series."""
    s, c, term, k = 0, 0, ONE, 0  # term = r^k / k!
    while term:
        if k % 4 == 0:
            c += term
        elif k % 4 == 1:
            s += term
        elif k % 4 == 2:
            c -= term
        else:
            s -= term
        k += 1
        term = term * r // ONE // k
    return s, c


def sin_cos(x: float) -> tuple[Fraction, Fraction]:
    """(sin x, cos x) to ~2**-230 as Fractions."""
    v = fixed(x)
    k = (2 * v + PI // 2) // PI  # nearest multiple of pi/2
    r = v - k * PI // 2
    s, c = _sin_cos_small(r)
    s, c = [(s, c), (c, -s), (-s, -c), (-c, s)][k % 4]
    return Fraction(s, ONE), Fraction(c, ONE)


def _atan_fixed(t: int) -> int:
    """atan t for 0 <= t <= 1 (fixed point): halve the angle three times, then Taylor."""
    halvings = 0
    while t > ONE // 8:
        t = t * ONE // (ONE + math.isqrt(ONE * ONE + t * t))  # tan(a/2) = t / (1 + sqrt(1 + t^2))
        halvings += 1
    total, term, k, t2 = 0, t, 0, t * t // ONE
    while term:
        total += term // (2 * k + 1) if k % 2 == 0 else -(term // (2 * k + 1))
        term = term * t2 // ONE
        k += 1
    return total << halvings


def atan2(y: float, x: float) -> Fraction:
    """atan2(y, x) for finite x, y not both zero, to ~2**-230."""
    fy, fx = Fraction(y), Fraction(x)
    ay, ax = abs(fy), abs(fx)
    swapped = ay > ax
    t = ax / ay if swapped else ay / ax
    a = _atan_fixed(t.numerator * ONE // t.denominator)
    if swapped:
        a = PI // 2 - a
    if fx < 0:
        a = PI - a
    return Fraction(-a if fy < 0 else a, ONE)


def ulps(value: float, exact: Fraction) -> float:
    """|value - exact| in units in the last place of the float nearest to exact."""
    return float(abs(Fraction(value) - exact) / Fraction(math.ulp(float(exact))))
