"""The one compiled pass of reading a PLY whose lists differ in length from row to row (io/meshes/ply_lists.py):
every row's start and counts, which depend on the rows before it."""

from __future__ import annotations

from ...jit import kernel


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

