"""x^f of the specular highlight: float32 computed here in float64 arithmetic, the same bits on every machine
and in vector registers; float64 by the C library's pow.

libm's powf is a call LLVM cannot vectorise (5 of the 18.5 ms of shading on ico6 at 1000², one thread), and
its last bit differs between C libraries (glibc's is off the correctly rounded value for about 1 x in 2,000).
For 0 < x < ∞ and finite f ≥ 0 (specular_power handles the rest):

    x = m 2^e with m in [√½, √2)        ln m = 2 atanh s = 2 (s + s³/3 + … + s¹⁷/17),  s = (m − 1)/(m + 1)
    y = f (e ln 2 + ln m)               x^f = exp y = 2^n exp r,  n = round(y / ln 2),  r = y − n ln 2

|s| ≤ 0.172 and |r| ≤ 0.347 bound the series' truncations (the next terms) below 1e-15. The float64 result is
within about 1e-13 of x^f (the rounding of y, |y| ≤ 130 after clamping, dominates), so rounded to float32 it is
the correctly rounded x^f except where x^f lies within 1e-13 of a halfway point: off by one unit in the last
place at most (tests/renderer/kernels/test_power.py). y is clamped to [−130, 90] first: beyond it the float32
result is 0 or inf anyway, and 2^n stays a normal float64.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic, overload

LN2_HI = 6.93147180369123816490e-01  # ln 2 split: n × LN2_HI is exact for |n| < 2^20 (fdlibm's constants)
LN2_LO = 1.90821492927058770002e-10
INV_LN2 = 1.44269504088896338700e+00
SQRT2 = 1.4142135623730951
MANTISSA = (1 << 52) - 1
EXPONENT_ONE = 1023 << 52  # the bits of 1.0
ZERO32 = np.float32(0)
LOW, HIGH = -130.0, 90.0  # e^-130 < 2^-150 rounds to float32 0; e^90 > float32's largest


@intrinsic
def _bits(typingctx, x):
    """The bits of a float64 as an int64 (a bitcast: no conversion)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.int64(types.float64), codegen


@intrinsic
def _from_bits(typingctx, b):
    """The float64 whose bits are the int64 b."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.int64), codegen


def power(x, f):
    """x^f, x > 0 (the Python twin of the kernels' version: the C library's pow)."""
    return x ** f


def _power32(x, f):
    """x^f for float32 x > 0 and finite f ≥ 0 (module docstring), branch-free so a loop over lanes vectorises."""
    b = _bits(float(x))
    e = (b >> 52) - 1023
    m = _from_bits((b & MANTISSA) | EXPONENT_ONE)
    big = m > SQRT2  # arithmetic, not an `if`: numba's inliner mis-scopes a branch's variables (a pedantic warning)
    m *= 1.0 - 0.5 * big
    e += big
    s = (m - 1.0) / (m + 1.0)
    z = s * s
    series = 1.0 + z * (1.0 / 3 + z * (1.0 / 5 + z * (1.0 / 7 + z * (1.0 / 9 + z * (
        1.0 / 11 + z * (1.0 / 13 + z * (1.0 / 15 + z * (1.0 / 17))))))))
    ln_x = e * LN2_HI + (e * LN2_LO + 2.0 * s * series)
    y = min(max(float(f) * ln_x, LOW), HIGH)
    n = float(int(y * INV_LN2 + 65536.5) - 65536)  # round to nearest; the offset keeps the truncation a floor
    r = (y - n * LN2_HI) - n * LN2_LO
    exp_r = 1.0 + r * (1.0 + r * (1.0 / 2 + r * (1.0 / 6 + r * (1.0 / 24 + r * (1.0 / 120 + r * (
        1.0 / 720 + r * (1.0 / 5040 + r * (1.0 / 40320 + r * (1.0 / 362880 + r * (
            1.0 / 3628800 + r * (1.0 / 39916800 + r * (1.0 / 479001600))))))))))))
    # + min(x, 0): 0 for any x ≥ 0 (inf too), and a NaN x stays NaN (np.minimum propagates it), without a branch.
    return np.float32(exp_r * _from_bits((int(n) + 1023) << 52)) + np.minimum(x, ZERO32)


@overload(power, inline="always", jit_options={"error_model": "numpy"})
def _power(x, f):
    if isinstance(x, types.Float) and x.bitwidth == 32:
        return _power32
    return lambda x, f: x ** f
