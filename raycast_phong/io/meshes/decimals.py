"""Decimal numbers in a text mesh file read by compiled code to the very bits numpy's or Python's parse gives
(a plain OBJ's coordinates, an ASCII PLY's rows): Clinger's fast path, m × 10^e with both exact in float64.
A word outside that path is left to numpy, so nothing read here differs from the parse it replaces."""

from __future__ import annotations

import numpy as np

from ...jit import kernel

POWERS = np.array([10.0 ** k for k in range(23)])  # 1e0 .. 1e22: every one exact in float64
EXACT = 1 << 53  # integers up to this are exact in float64


@kernel(inline="always")
def numeric(c):
    """A byte a plain decimal coordinate is written with: digits, sign, point, exponent."""
    return (48 <= c <= 57) or c == 43 or c == 45 or c == 46 or c == 101 or c == 69


@kernel()
def decimal(data, start, stop, powers):
    """(value, exact) of the word data[start:stop]: [+-] digits [. digits] [(e|E) [+-] digits] with a digit
    before the exponent, read as m × 10^e with m below 2^53 and |e| ≤ 22: then m and 10^|e| are exact in float64
    and one product or quotient rounds the decimal's exact value correctly, the value every correct reader
    (numpy's, Python's float) gives (Clinger's fast path). exact False: another word, or one outside that path."""
    i, negative = start, False
    if i < stop and (data[i] == 43 or data[i] == 45):
        negative = data[i] == 45
        i += 1
    mantissa, digits, scale, point = 0, 0, 0, False
    while i < stop:
        c = data[i]
        if 48 <= c <= 57:
            if mantissa >= EXACT // 10:  # one more digit could pass 2^53 (a trailing zero is left to the slow path)
                return 0.0, False
            mantissa = 10 * mantissa + (c - 48)
            digits += 1
            if point:
                scale -= 1
        elif c == 46 and not point:
            point = True
        else:
            break
        i += 1
    if digits == 0:
        return 0.0, False
    if i < stop:
        if data[i] != 101 and data[i] != 69:
            return 0.0, False
        i += 1
        sign = 1
        if i < stop and (data[i] == 43 or data[i] == 45):
            sign = -1 if data[i] == 45 else 1
            i += 1
        if i == stop:
            return 0.0, False
        exponent = 0
        while i < stop:
            c = data[i]
            if c < 48 or c > 57 or exponent > 1000:
                return 0.0, False
            exponent = 10 * exponent + (c - 48)
            i += 1
        scale += sign * exponent
    if scale > 22 or scale < -22:
        return 0.0, False
    value = float(mantissa) * powers[scale] if scale >= 0 else float(mantissa) / powers[-scale]
    return (-value if negative else value), True
