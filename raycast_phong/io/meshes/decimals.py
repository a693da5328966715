"""Decimal numbers in a text mesh file read by compiled code to the very bits numpy's or Python's parse gives
(a plain OBJ's coordinates; an ASCII PLY's and an OFF's lines of numbers, number_lines): Clinger's fast path,
m × 10^e with both exact in float64. A word outside that path is left to numpy, so nothing read here differs
from the parse it replaces. One pass over a 40 MB file takes ~0.15 s of CPU, numpy's text parse ~1 s."""

from __future__ import annotations

import warnings

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


LF, HASH = 10, 35


@kernel(inline="always")
def line_end(data, at):
    """(end, stop) of the line starting at byte `at` of `data`: the LF that ends it (or the data's end) and where
    its text stops, before a CR of a CRLF line end."""
    end = at
    while end < data.shape[0] and data[end] != LF:
        end += 1
    return end, end - 1 if end > at and data[end - 1] == 13 else end


@kernel(inline="always")
def _blank(c):
    """A byte that separates words on a line: what Python's bytes.split() splits on but the line feed."""
    return c == 32 or c == 9 or c == 13 or c == 11 or c == 12


@kernel()
def number_lines(data, at, rows, comments, powers, words, values):
    """(lines, total, exact, end) of reading up to `rows` lines of numbers from byte `at` of `data` (uint8):
    words separated by _blank bytes, lines ending in LF (the last may end with the data). With `comments`
    (OFF), a `#` ends a line's words and a line without words is no row; without (PLY), every line is a row.
    words[k] gets row k's count; `values` the numbers in order while they fit, read by `decimal` while every
    word so far is on its exact path (`exact`). `lines`: the rows read (fewer when the data ends first);
    `total`: their words, counted past `values`' end; `end`: the byte after the last row's line."""
    n = data.shape[0]
    capacity = values.shape[0]
    line = total = 0
    exact = True
    while line < rows and at < n:
        count = 0
        while True:
            while at < n and _blank(data[at]):
                at += 1
            if at >= n or data[at] == LF:
                break
            if comments and data[at] == HASH:
                while at < n and data[at] != LF:
                    at += 1
                break
            start = at
            while at < n and data[at] != LF and not _blank(data[at]) and not (comments and data[at] == HASH):
                at += 1
            if exact and total < capacity:
                value, exact = decimal(data, start, at, powers)
                values[total] = value
            total += 1
            count += 1
        at += 1
        if count == 0 and comments:
            continue
        words[line] = count
        line += 1
    return line, total, exact, min(at, n)


def lines_of_numbers(text: np.ndarray, at: int, rows: int, comments: bool, expected: int, grow: bool):
    """(words per line, the numbers in order or None where a word is off the exact path, the byte after the last
    line) of the next `rows` lines of `text` (uint8) from byte `at`, by number_lines; `expected` numbers are
    made room for, and more with `grow`. None when the data ends first, or without `grow` the lines hold more."""
    words, values = np.empty(rows, np.int64), np.empty(expected)
    lines, total, exact, end = number_lines(text, at, rows, comments, POWERS, words, values)
    if lines == rows and total > expected and grow:
        values = np.empty(total)
        lines, total, exact, end = number_lines(text, at, rows, comments, POWERS, words, values)
    if lines != rows or total > len(values):
        return None
    return words, values[:total] if exact else None, end


def numpy_rows(text: bytes, rows: int, width: int) -> np.ndarray | None:
    """(rows, width) float64 of `text` by numpy's parse (np.fromstring, the call trimesh's readers make, so its
    bits); None where numpy reads another count of numbers (a word that is not one stops it short)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numpy 1 warns where it stops short: counted below
            values = np.fromstring(text, sep=" ")
    except ValueError:  # numpy 2 raises where it stops
        return None
    return values.reshape(rows, width) if values.size == rows * width else None
