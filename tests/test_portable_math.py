"""generator/geometry/portable_math.py: sine, cosine and arctangent within 1 ulp of references
computed in exact integer arithmetic (tests/fixed_point_math.py), with the C library's
special values, and the same bits whatever CPU numba compiles for."""

import math
import os
import platform
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import fixed_point_math as ref
from conftest import cpu_flags
from generator.geometry import portable_math as pm

ROOT = Path(__file__).resolve().parents[1]


def _angles() -> np.ndarray:
    rng = np.random.default_rng(7)
    return np.concatenate([rng.uniform(-4, 4, 1500), rng.uniform(-pm.MAX_ANGLE, pm.MAX_ANGLE, 400),
                           rng.uniform(-1e-4, 1e-4, 200), np.arange(-60, 61) * (np.pi / 4),
                           np.arange(-60, 61) * (np.pi / 2) + 1e-9, [pm.MAX_ANGLE, -pm.MAX_ANGLE]])


def test_constants_are_the_splits_of_pi_they_claim():
    pio2 = Fraction(ref.PI, ref.ONE) / 2
    assert abs(Fraction(pm.PIO2_1) + Fraction(pm.PIO2_2) + Fraction(pm.PIO2_3) - pio2) < Fraction(1, 10**36)  # PIO2_3's rounding
    for part in (pm.PIO2_1, pm.PIO2_2):  # 33 significant bits: k * part exact for |k| < 2**20
        mantissa = Fraction(part) / Fraction(2) ** math.frexp(part)[1]
        assert (mantissa * 2**33).denominator == 1
    assert abs(pm.MAX_ANGLE * pm.TWO_OVER_PI) < 2**20
    for c, hi, lo in zip(pm.ATAN_CENTRES, pm.ATAN_HI, pm.ATAN_LO):
        if c > 0:
            assert abs(Fraction(hi) + Fraction(lo) - ref.atan2(float(c), 1.0)) < Fraction(1, 10**30)


def test_sine_and_cosine_are_within_one_ulp():
    x = _angles()
    s, c = pm.sincos(x)
    worst_s = max(ref.ulps(float(v), ref.sin_cos(float(a))[0]) for v, a in zip(s, x))
    worst_c = max(ref.ulps(float(v), ref.sin_cos(float(a))[1]) for v, a in zip(c, x))
    assert worst_s < 1.0 and worst_c < 1.0, (worst_s, worst_c)
    assert np.array_equal(pm.tan(x[:50]), s[:50] / c[:50])


def test_arctangent_is_within_one_ulp():
    rng = np.random.default_rng(8)
    y = rng.normal(size=2500) * 10.0 ** rng.uniform(-6, 6, 2500)
    x = rng.normal(size=2500) * 10.0 ** rng.uniform(-6, 6, 2500)
    y[:300], x[300:600] = x[:300] * rng.uniform(0.99, 1.01, 300), 0.0  # near the diagonal; on the axes
    # ratios on both sides of each breakpoint of the reduction, below and above the diagonal,
    # in all four quadrants; then operands near the top and the bottom of the float range
    ratio = np.concatenate([b * (1 + rng.uniform(-0.05, 0.05, 150)) for b in (*pm.ATAN_BREAKS, 1.0)])
    ratio = np.concatenate([ratio, 1 / ratio])
    sign_y, sign_x = rng.choice([-1.0, 1.0], (2, len(ratio)))
    size = 10.0 ** rng.uniform(-3, 3, len(ratio))
    y, x = np.concatenate([y, sign_y * ratio * size]), np.concatenate([x, sign_x * size])
    big, small = rng.uniform(0.1, 1, (2, 100)) * 1e300, rng.uniform(0.1, 1, (2, 100)) * 1e-310
    y, x = np.concatenate([y, big[0], small[0]]), np.concatenate([x, big[1] * 1.7, small[1] * 0.6])
    out = pm.atan2(y, x)
    worst = max(ref.ulps(float(v), ref.atan2(float(b), float(a))) for v, b, a in zip(out, y, x))
    assert worst < 1.0, worst


@pytest.mark.parametrize("y, x", [(0.0, 0.0), (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0), (1.0, 0.0), (-1.0, -0.0),
                                  (0.0, -1.0), (-0.0, -1.0), (1.0, 1.0), (math.inf, 1.0), (1.0, -math.inf),
                                  (-math.inf, math.inf), (3.0, math.inf), (math.nan, 1.0)])
def test_arctangent_special_values_are_the_c_librarys(y, x):
    want, got = math.atan2(y, x), pm.atan2(y, x)
    assert (math.isnan(want) and math.isnan(got)) or (got == want and math.copysign(1, got) == math.copysign(1, want))


def test_zeros_non_finite_and_out_of_range_angles():
    assert math.copysign(1.0, pm.sin(-0.0)) < 0 and pm.cos(-0.0) == 1.0
    assert pm.sin(5e-324) == 5e-324 and pm.sin(-1e-300) == -1e-300  # below the reference's resolution
    assert all(math.isnan(v) for v in pm.sincos(math.inf) + pm.sincos(math.nan))
    with pytest.raises(ValueError, match="beyond the supported"):
        pm.sin(np.array([0.0, 2e5]))
    assert isinstance(pm.sin(0.5), float) and pm.sincos(np.zeros((2, 3)))[1].shape == (2, 3)
    assert pm.vector_norm([3.0, 4.0]) == 5.0 and pm.hypot(3.0, 4.0) == 5.0
    assert np.array_equal(pm.vector_norm(np.array([[1.0, 2.0, 2.0], [0.0, 0.0, 0.0]])), [3.0, 0.0])


PROBE = """
import hashlib
import numba
import numpy as np
from generator.geometry import portable_math as pm


@numba.njit(fastmath=True)
def fused(a, b, c):  # the control: fast-math lets LLVM fuse a * b + c where the target has FMA
    return a * b + c


rng = np.random.default_rng(0)
x = np.concatenate([rng.uniform(-4, 4, 20000), rng.uniform(-1e5, 1e5, 5000)])
print(hashlib.sha256(b"".join(a.tobytes() for a in pm.sincos(x) + (pm.atan2(x, x[::-1]),))).hexdigest(),
      hashlib.sha256(fused(x, x[::-1], -x).tobytes()).hexdigest())
"""


def test_results_do_not_depend_on_the_cpu_numba_compiles_for(tmp_path):
    """numba compiles for the CPU it runs on; NUMBA_CPU_NAME makes it compile for another one
    (with a cache of its own): generic x86-64, Sandy Bridge (no FMA) and Haswell (FMA, AVX2)
    must all give the bits of this machine's own build. The README's machines (x86-64 with
    AVX2 and FMA) can run all four; anywhere else this fails saying so, it does not skip."""
    assert platform.machine() == "x86_64" and {"avx", "avx2", "fma"} <= cpu_flags(), \
        "this test needs an x86-64 CPU with AVX2 and FMA (it runs Sandy Bridge and Haswell builds here)"
    digests, controls = set(), set()
    for name in ("host", "generic", "sandybridge", "haswell"):
        env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / name))
        if name != "host":
            env["NUMBA_CPU_NAME"] = name
        out = subprocess.run([sys.executable, "-c", PROBE], env=env, cwd=ROOT, capture_output=True, text=True)
        assert out.returncode == 0, out.stderr[-2000:]
        ours, control = out.stdout.split()
        digests.add(ours)
        controls.add(control)
    assert len(digests) == 1
    assert len(controls) > 1, "NUMBA_CPU_NAME changed nothing: the comparison above saw one build four times"
