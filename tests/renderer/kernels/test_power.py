"""The highlight's x^f in float32 (kernels/power.py) against the exact power, and float64's against libm's.

For float32 x, x^f in float64 (numpy's pow: within an ulp of 2^-52) rounded to float32 is the correctly rounded
value unless x^f lies within 2^-52 of a halfway point between two float32 values; power.py's float64 result is
within about 1e-13 of x^f, so it may round the other way only where x^f is within 1e-13 (relative) of a halfway
point. Theory therefore allows: never more than one unit in the last place from the reference, and a different
rounding for a fraction of the values of the order of 1e-13 / 2^-24 ≈ 2e-6 (more where x^f can be exactly a
halfway point: x² of a float32 has 48 bits, so some x² are exact ties; those are counted apart).
"""

import math

import numba
import numpy as np
import pytest

from raycast_phong.renderer.kernels.power import power


@numba.njit(error_model="numpy")
def _powers(x, f, out):
    for i in range(x.shape[0]):
        out[i] = power(x[i], f)


def powers(x: np.ndarray, f) -> np.ndarray:
    out = np.empty_like(x)
    _powers(x, x.dtype.type(f), out)
    return out


def cosines() -> np.ndarray:
    """Cosines as the highlight sees them: uniform in (0, 1], crowded just below 1 (the highlight's centre),
    tiny ones, and every float32 between 0.999 and 1."""
    rng = np.random.default_rng(22)
    near_one = np.arange(np.float32(0.999).view(np.int32), np.float32(1).view(np.int32) + 1, dtype=np.int32)
    return np.concatenate([rng.random(400_000), 1 - rng.random(200_000) * 1e-5, rng.random(10_000) * 1e-30,
                           near_one.view(np.float32)]).astype(np.float32)


def ulps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Units in the last place between float32 values of one sign."""
    return np.abs(a.view(np.int32).astype(np.int64) - b.view(np.int32).astype(np.int64))


@pytest.mark.parametrize("f", [0.5, 1.0, 3.0, 8.0, 32.0, 100.0, 1000.0, 12345.678, 1e6, 1e30])
def test_float32_power_is_the_correctly_rounded_power_but_for_near_ties(f):
    x = cosines()
    with np.errstate(under="ignore"):
        exact = (x.astype(np.float64) ** np.float64(np.float32(f))).astype(np.float32)
    got = powers(x, f)
    assert ulps(got, exact).max() <= 1
    assert np.count_nonzero(got != exact) <= max(2, 1e-5 * len(x))


def test_float32_power_of_exact_ties_is_within_one_unit():
    """x² of a float32 can be exactly halfway between two float32 values: then either neighbour is within the
    documented bound (numpy's rounding to even picks one; power.py's 1e-13 error may pick the other)."""
    x = cosines()
    exact = (x.astype(np.float64) ** 2).astype(np.float32)
    got = powers(x, 2.0)
    assert ulps(got, exact).max() <= 1
    assert np.count_nonzero(got != exact) <= 1e-3 * len(x)


def test_float32_power_limits():
    x = np.array([0.0, 1.0, np.inf, np.nan, 1e-45, 1.0000001], np.float32)
    assert powers(x, 0.0)[[1, 2, 4, 5]].tolist() == [1.0, 1.0, 1.0, 1.0]  # x^0 = 1 for every x > 0
    got = powers(x, 5.0)
    assert got[0] == 0 and got[1] == 1 and got[2] == np.inf and np.isnan(got[3]) and got[4] == 0
    assert got[5] == np.float32(np.float64(np.float32(1.0000001)) ** 5)
    assert powers(np.array([0.5], np.float32), 1e30)[0] == 0  # underflows to 0, no NaN from the clamp
    assert powers(np.array([1.0000001], np.float32), 1e30)[0] == np.inf


def test_float64_power_is_the_c_librarys():
    """float64 keeps the C library's pow (math.pow calls it; numpy's own vector pow may differ in the last bit)."""
    x = cosines().astype(np.float64)[::61]
    assert np.array_equal(powers(x, 37.5), np.array([math.pow(v, 37.5) for v in x]))
