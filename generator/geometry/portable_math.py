"""Sine, cosine and arctangent that give the same bits on every CPU (numba, cached on disk).

numpy's float64 ``sin``/``cos`` call the C library, whose x86-64 build picks an FMA or a
plain variant by CPU, and its ``arctan2``, ``arctan``, ``tan``, ``exp``, ``log`` and
``power`` use AVX-512 kernels where the CPU has them: all round differently by machine
(``tests/test_same_bytes.py`` shows it with ``GLIBC_TUNABLES`` and
``NPY_DISABLE_CPU_FEATURES`` as stand-ins for other CPUs). A site, its trajectories and its
boxes are made from angles, so a seed's geometry went through them. The functions here use
only IEEE float64 multiplies, adds, divides and square roots in a fixed order (numba without
``fastmath`` neither reorders nor fuses them), so their results do not depend on the CPU.
``sin``, ``cos`` and ``atan2`` are within 1 ulp of the true value (0.75 ulp at most over the test's samples, against
references in exact integer arithmetic: ``tests/fixed_point_math.py``); the C library is
within 0.51 ulp, so the two may differ in the last bit.

- :func:`sin`, :func:`cos`, :func:`sincos`, :func:`tan`: arguments in radians, ``|x| <= 1e5``
  (a ValueError beyond; every angle of a site is far smaller); not finite gives NaN.
- :func:`atan2`: ``atan2(y, x)`` in [-pi, pi], with C's results for zeros and infinities.
- :func:`hypot`: ``sqrt(x x + y y)``; :func:`vector_norm`: the length of vectors along the
  last axis, summed in order (``np.linalg.norm`` of one vector is BLAS's dot product, whose
  kernel depends on the CPU); no care for overflow (metres, not 1e154).

Scalars in give Python floats out; arrays (broadcast together) give float64 arrays.
"""

from __future__ import annotations

import math

import numba
import numpy as np

MAX_ANGLE = 1e5  # radians: the range reduction below is exact for |k| < 2**20 quarter turns

# pi/2 = PIO2_1 + PIO2_2 + PIO2_3 to ~1e-37: the first two have 33 significant bits, so
# k * PIO2_1 and k * PIO2_2 are exact for |k| < 2**20 (the test re-derives all constants).
PIO2_1 = float.fromhex("0x1.921fb54400000p+0")
PIO2_2 = float.fromhex("0x1.0b4611a600000p-34")
PIO2_3 = float.fromhex("0x1.3198a2e037073p-69")
TWO_OVER_PI = float.fromhex("0x1.45f306dc9c883p-1")
PI_HI, PI_LO = float.fromhex("0x1.921fb54442d18p+1"), float.fromhex("0x1.1a62633145c07p-53")
PIO2_HI, PIO2_LO = float.fromhex("0x1.921fb54442d18p+0"), float.fromhex("0x1.1a62633145c07p-54")
# atan(c) = ATAN_HI[i] + ATAN_LO[i] for c = 0, 1/2, 3/4, 1 (the last is pi/4)
ATAN_HI = np.array([0.0, float.fromhex("0x1.dac670561bb4fp-2"), float.fromhex("0x1.4978fa3269ee1p-1"),
                    float.fromhex("0x1.921fb54442d18p-1")])
ATAN_LO = np.array([0.0, float.fromhex("0x1.a2b7f222f65e2p-56"), float.fromhex("0x1.2419a87f2a458p-56"),
                    float.fromhex("0x1.1a62633145c07p-55")])
ATAN_CENTRES = np.array([0.0, 0.5, 0.75, 1.0])
ATAN_BREAKS = np.array([0.4375, 0.6875, 0.875])  # t below the first: c = 0; then 1/2, 3/4, 1
# Taylor coefficients: sin r = r + r z (S[0] + z (S[1] + ...)), z = r^2, terms to r^21;
# cos r = 1 - z/2 + z^2 (C[0] + z (C[1] + ...)), terms to r^22. On |r| <= pi/4 the first
# term left out is below 2e-25 relative.
SIN_COEFFS = np.array([(-1.0) ** (k + 1) / math.factorial(2 * k + 3) for k in range(10)])
COS_COEFFS = np.array([(-1.0) ** k / math.factorial(2 * k + 4) for k in range(10)])
# atan u = u + u v (A[0] + v (A[1] + ...)), v = u^2, terms to u^49: the first left out is
# below 1e-18 relative for |u| <= 7/16.
ATAN_COEFFS = np.array([(-1.0) ** k / (2 * k + 1) for k in range(1, 25)])
SPLITTER = 134217729.0  # 2^27 + 1: Veltkamp's split of a float64 into two 26-bit halves
TINY = 2.0 ** -900  # below this, atan t = t to the last bit and Dekker's product could underflow


@numba.njit(cache=True, nogil=True)
def _sin_kernel(r, rr, z):
    """sin(r + rr) for |r| <= pi/4 + a little, rr the reduced argument's tail (|rr| << ulp r):
    sin r + rr cos r, with cos r ~ 1 - z/2 in the tail."""
    p = SIN_COEFFS[9]
    for k in range(8, -1, -1):
        p = SIN_COEFFS[k] + z * p
    return r + ((r * z) * p + rr * (1.0 - 0.5 * z))


@numba.njit(cache=True, nogil=True)
def _cos_kernel(r, rr, z):
    """cos(r + rr) = cos r - rr sin r (sin r ~ r in the tail)."""
    p = COS_COEFFS[9]
    for k in range(8, -1, -1):
        p = COS_COEFFS[k] + z * p
    half = 0.5 * z
    w = 1.0 - half
    # (1 - w) is exact, so ((1 - w) - half) is the rounding error of w, carried in the tail
    return w + (((1.0 - w) - half) + ((z * z) * p - r * rr))


@numba.njit(cache=True, nogil=True)
def _reduce(x):
    """x = k pi/2 + r + rr with |r| <= ~pi/4 and rr the tail of r (Cody and Waite's reduction
    with the subtraction's rounding error kept: Knuth's two-sum)."""
    k = math.floor(x * TWO_OVER_PI + 0.5)
    a = x - k * PIO2_1  # exact: k PIO2_1 is exact and close to x (Sterbenz)
    b = -(k * PIO2_2)   # exact product
    hi = a + b
    bv = hi - a
    lo = (a - (hi - bv)) + (b - bv)  # the rounding error of a + b
    lo = lo - k * PIO2_3
    r = hi + lo
    return k, r, lo - (r - hi)


@numba.njit(cache=True, nogil=True)
def _sincos_one(x):
    if not math.isfinite(x):
        return math.nan, math.nan
    if x == 0.0:
        return x, 1.0  # keeps the sign of a zero
    k, r, rr = _reduce(x)
    z = r * r
    s, c = _sin_kernel(r, rr, z), _cos_kernel(r, rr, z)
    quadrant = int(k) & 3
    if quadrant == 0:
        return s, c
    if quadrant == 1:
        return c, -s
    if quadrant == 2:
        return -s, -c
    return -c, s


@numba.njit(cache=True, nogil=True)
def _sincos_array(x, s, c):
    for i in range(x.shape[0]):
        s[i], c[i] = _sincos_one(x[i])


@numba.njit(cache=True, nogil=True)
def _two_diff(a, b):
    """(s, e) with s = fl(a - b) and a - b = s + e exactly (Knuth's two-sum of a and -b)."""
    s = a - b
    bv = s - a
    return s, (a - (s - bv)) - (b + bv)


@numba.njit(cache=True, nogil=True)
def _product_error(a, b):
    """a b - fl(a b) exactly (Dekker's product without FMA; |a|, |b| <= 1 and a b not tiny)."""
    p = a * b
    ca, cb = SPLITTER * a, SPLITTER * b
    ah, bh = ca - (ca - a), cb - (cb - b)
    al, bl = a - ah, b - bh
    return ((ah * bh - p) + ah * bl + al * bh) + al * bl


@numba.njit(cache=True, nogil=True)
def _atan_unit(t, tt):
    """atan(t + tt) for 0 <= t <= 1 (tt: t's tail) as (hi, lo): atan c of the centre c for t's
    interval plus atan((t - c) / (1 + t c)), |u| <= 7/16 (t - c is exact: Sterbenz), plus
    tt / (1 + t^2)."""
    i = 0
    while i < 3 and t >= ATAN_BREAKS[i]:
        i += 1
    c = ATAN_CENTRES[i]
    u = (t - c) / (1.0 + t * c)
    v = u * u
    p = ATAN_COEFFS[23]
    for k in range(22, -1, -1):
        p = ATAN_COEFFS[k] + v * p
    return ATAN_HI[i], ATAN_LO[i] + (u + ((u * v) * p + tt / (1.0 + t * t)))


@numba.njit(cache=True, nogil=True)
def _atan2_one(y, x):
    if math.isnan(x) or math.isnan(y):
        return math.nan
    ax, ay = abs(x), abs(y)
    swapped = ay > ax
    if math.isinf(ax) and math.isinf(ay):
        t, tt = 1.0, 0.0
    elif ax == 0.0 and ay == 0.0:
        t, tt = 0.0, 0.0
    else:
        num, den = (ax, ay) if swapped else (ay, ax)
        if den != math.inf:  # scale both by a power of two (exact) so that 0.5 <= den < 1
            exponent = math.frexp(den)[1]
            num, den = math.ldexp(num, -exponent), math.ldexp(den, -exponent)
        t = num / den
        # the division's rounding error: num = t den + (num - t den), the last term exact
        # (Dekker's product; below 2^-900 t alone is atan t to the last bit)
        tt = ((num - t * den) - _product_error(t, den)) / den if TINY < t and den != math.inf else 0.0
    hi, lo = _atan_unit(t, tt)
    if swapped:  # pi/2 - atan t, the subtraction's rounding error carried into the tail
        hi, err = _two_diff(PIO2_HI, hi)
        lo = (PIO2_LO - lo) + err
    if x < 0.0 or (x == 0.0 and math.copysign(1.0, x) < 0.0):  # pi - a
        hi, err = _two_diff(PI_HI, hi)
        lo = (PI_LO - lo) + err
    a = hi + lo
    return -a if (y < 0.0 or (y == 0.0 and math.copysign(1.0, y) < 0.0)) else a


@numba.njit(cache=True, nogil=True)
def _atan2_array(y, x, out):
    for i in range(x.shape[0]):
        out[i] = _atan2_one(y[i], x[i])


def _result(values: np.ndarray, scalar: bool):
    return float(values.reshape(())) if scalar else values


def sincos(x):
    """(sin x, cos x) for x in radians, ``|x| <= 1e5``; the same bits on every CPU."""
    a = np.asarray(x, dtype=np.float64)
    finite = a[np.isfinite(a)]
    if finite.size and np.abs(finite).max() > MAX_ANGLE:
        raise ValueError(f"portable_math: angle {np.abs(finite).max():g} rad is beyond the supported "
                         f"|x| <= {MAX_ANGLE:g}; reduce it modulo 2 pi first")
    flat = np.ascontiguousarray(a.ravel())
    s, c = np.empty_like(flat), np.empty_like(flat)
    _sincos_array(flat, s, c)
    return _result(s.reshape(a.shape), a.ndim == 0), _result(c.reshape(a.shape), a.ndim == 0)


def sin(x):
    """sin x, x in radians (see :func:`sincos`)."""
    return sincos(x)[0]


def cos(x):
    """cos x, x in radians (see :func:`sincos`)."""
    return sincos(x)[1]


def tan(x):
    """tan x = sin x / cos x (within 3 ulp: two results within 1 ulp and a division), x in
    radians (see :func:`sincos`)."""
    s, c = sincos(x)
    return s / c


def atan2(y, x):
    """The angle of (x, y) in radians, in [-pi, pi] (C's conventions for signed zeros,
    infinities and NaN); the same bits on every CPU."""
    y, x = np.broadcast_arrays(np.asarray(y, dtype=np.float64), np.asarray(x, dtype=np.float64))
    fy, fx = np.ascontiguousarray(y.ravel()), np.ascontiguousarray(x.ravel())
    out = np.empty_like(fx)
    _atan2_array(fy, fx, out)
    return _result(out.reshape(x.shape), x.ndim == 0)


def hypot(x, y):
    """sqrt(x x + y y) in IEEE arithmetic (no overflow guard); the same bits on every CPU."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    out = np.sqrt(x * x + y * y)
    return float(out) if out.ndim == 0 else out


def vector_norm(v):
    """Lengths of vectors along the last axis: sqrt((v0 v0 + v1 v1) + ...) in IEEE arithmetic;
    one vector gives a float."""
    v = np.asarray(v, dtype=np.float64)
    total = v[..., 0] * v[..., 0]
    for k in range(1, v.shape[-1]):
        total = total + v[..., k] * v[..., k]
    out = np.sqrt(total)
    return float(out) if out.ndim == 0 else out
