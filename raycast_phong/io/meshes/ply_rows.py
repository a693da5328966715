"""The compiled passes of reading a PLY (io/meshes/ply_lists.py): every row's start and counts in a binary PLY
whose lists differ in length from row to row (they depend on the rows before it), and an ASCII PLY's rows of
numbers in one pass."""

from __future__ import annotations

from ...jit import kernel
from .decimals import decimal


@kernel()
def walk_rows(data, at, rows, sizes, counts, entries, signed, big, starts, found):
    """Every row's start (starts, rows + 1 of them) and every list's count (found, rows × lists) of a binary
    PLY element from byte `at` of `data` (uint8). Property k is a scalar of sizes[k] bytes when counts[k] is
    0, else a list: a count of counts[k] bytes (signed[k]: two's complement), then that many entries of
    entries[k] bytes; `big`: big-endian. Returns False when a count is negative or the rows run past the data."""
    n = data.shape[0]
    for row in range(rows):
        starts[row] = at
        listed = 0
        for k in range(sizes.shape[0]):
            if counts[k] == 0:
                at += sizes[k]
                continue
            width = counts[k]
            if at + width > n:
                return False
            value = 0
            for b in range(width):
                byte = data[at + (width - 1 - b if not big else b)]
                value = value * 256 + byte
            if signed[k] and value >= 1 << (8 * width - 1):
                value -= 1 << (8 * width)
            if value < 0:
                return False
            found[row, listed] = value
            listed += 1
            at += width + value * entries[k]
        if at > n:
            return False
    starts[rows] = at
    return True


SPACE, TAB, LF, CR = 32, 9, 10, 13


@kernel()
def number_rows(data, at, rows, width, powers, out):
    """(fits, exact, end) of reading `rows` lines of `width` numbers each from byte `at` of an ASCII PLY's
    `data` (uint8) into `out` (rows × width float64), words separated by spaces, tabs or CRs, each line ending
    in LF (the file's last may end with the data): fits False when a line holds another count of words or the
    data ends first; exact False when a word is not a decimal on decimals.decimal's exact path (`out` is then
    partly read: numpy's parse reads the section). `end` is the byte after the last line."""
    n = data.shape[0]
    exact = True
    for row in range(rows):
        if at >= n:
            return False, exact, at
        words = 0
        while True:
            while at < n and (data[at] == SPACE or data[at] == TAB or data[at] == CR):
                at += 1
            if at >= n or data[at] == LF:
                break
            start = at
            while at < n and data[at] != SPACE and data[at] != TAB and data[at] != CR and data[at] != LF:
                at += 1
            if words == width:
                return False, exact, at
            if exact:
                value, exact = decimal(data, start, at, powers)
                out[row, words] = value
            words += 1
        if words != width:
            return False, exact, at
        at += 1
    return True, exact, min(at, n)
