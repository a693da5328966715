"""An ASCII STL in the form exporters write (one `solid`, then `facet normal`, `outer loop`, three `vertex x y z`,
`endloop`, `endfacet` per triangle, `endsolid`) read in one compiled pass into what trimesh's reader gives for it.

trimesh's reader lowercases the whole text, splits it at every "vertex" and parses the pieces: 9.6 s of CPU for a
320 MB file of 1M facets, after trimesh's own import (0.25-0.7 s) for a file of any size. Here one compiled scan
(`_facets`) proves the file plain and reads the corners (decimals.decimal's exact path); where a coordinate is off
that path, the `vertex` lines' text is parsed by numpy as trimesh's reader parses it, so the bits are its. Anything
else (several solids, a facet of another count of vertices, a word that is not a plain number, a solid name
holding "vertex" or "endsolid", which trimesh's split would take apart) is trimesh's, which words every problem.
"""

from __future__ import annotations

import numpy as np

from ...jit import kernel
from .decimals import POWERS, decimal, line_end, numeric, numpy_rows
from .format import Part

SPACE, TAB = 32, 9
# The line kinds, by their first word (case-insensitive): what may follow each, in a plain file.
SOLID, FACET, OUTER, VERTEX, ENDLOOP, ENDFACET, ENDSOLID, OTHER = range(8)
KEYWORDS = (b"solid", b"facet", b"outer", b"vertex", b"endloop", b"endfacet", b"endsolid")
WORDS = np.zeros((len(KEYWORDS), 8), np.uint8)  # each keyword's bytes, zero-padded: what _kind compares with
for _row, _word in enumerate(KEYWORDS):
    WORDS[_row, :len(_word)] = np.frombuffer(_word, np.uint8)
LENGTHS = np.array([len(word) for word in KEYWORDS], np.int64)


@kernel(inline="always")
def _kind(data, start, stop, words, lengths):
    """The line kind of the word data[start:stop] (a KEYWORDS index, any case), or OTHER."""
    for k in range(lengths.shape[0]):
        if stop - start != lengths[k]:
            continue
        same = True
        for i in range(stop - start):
            if data[start + i] | 32 != words[k, i]:  # ASCII letters lowercased; the keywords are all letters
                same = False
                break
        if same:
            return k
    return OTHER


@kernel(inline="always")
def _plain_rest(data, i, stop):
    """Whether data[i:stop], the rest of a facet, outer loop, endloop or endfacet line, holds only numbers and the
    letters of `normal` and `loop`: no "vertex" or "solid" that trimesh's split would cut at."""
    for k in range(i, stop):
        c = data[k] | 32
        if not (numeric(data[k]) or data[k] == SPACE or data[k] == TAB or c == 110 or c == 111 or c == 114
                or c == 109 or c == 97 or c == 108 or c == 112):  # n o r m a l p
            return False
    return True


@kernel()
def _facets(data, mode, words, lengths, powers, points, vertex_text):
    """One pass over ASCII STL text `data` (uint8). Returns (plain, corners, text bytes, exact): whether the file
    is one solid of facets in the plain form (module docstring; blank lines anywhere, words separated by spaces or
    tabs, lines ending in LF or CRLF, nothing but blank lines after `endsolid`); its corners; the bytes of its
    `vertex` lines' text; and whether every coordinate was read exactly. mode 0 counts; 1 also reads the corners
    into points (C, 3) float64; 2 instead copies each `vertex` line's text after its keyword into vertex_text, for
    numpy to read."""
    n = data.shape[0]
    expected = SOLID  # the kind the next line must be (ENDSOLID also after endfacet; -1 past endsolid: no kind)
    corners = written = in_loop = 0
    exact = True
    at = 0
    while at < n:
        end, stop = line_end(data, at)
        i = at
        while i < stop and (data[i] == SPACE or data[i] == TAB):
            i += 1
        if i < stop:
            start = i
            while i < stop and data[i] != SPACE and data[i] != TAB:
                i += 1
            kind = _kind(data, start, i, words, lengths)
            if kind == VERTEX and expected == VERTEX:
                column = 0
                text_start = i
                while True:
                    while i < stop and (data[i] == SPACE or data[i] == TAB):
                        i += 1
                    if i == stop:
                        break
                    word = i
                    while i < stop and data[i] != SPACE and data[i] != TAB:
                        if not numeric(data[i]):
                            return False, corners, written, exact
                        i += 1
                    if column == 3:
                        return False, corners, written, exact
                    if mode == 1 and exact:
                        value, exact = decimal(data, word, i, powers)
                        points[corners, column] = value
                    column += 1
                if column != 3:
                    return False, corners, written, exact
                if mode == 2:
                    vertex_text[written] = SPACE
                    for k in range(stop - text_start):  # a loop: a slice assignment compiles its error text
                        vertex_text[written + 1 + k] = data[text_start + k]
                written += 1 + stop - text_start
                corners += 1
                in_loop += 1
                expected = ENDLOOP if in_loop == 3 else VERTEX
            elif kind == expected or (kind == ENDSOLID and expected == FACET and corners > 0):
                if kind != SOLID and kind != ENDSOLID and not _plain_rest(data, i, stop):
                    return False, corners, written, exact
                if kind == SOLID:
                    expected = FACET
                elif kind == FACET:
                    expected = OUTER
                elif kind == OUTER:
                    expected, in_loop = VERTEX, 0
                elif kind == ENDLOOP:
                    expected = ENDFACET
                elif kind == ENDFACET:
                    expected = FACET
                else:  # endsolid
                    expected = -1
            else:
                return False, corners, written, exact
        at = end + 1
    return expected == -1, corners, written, exact


def plain_stl(data: bytes) -> Part | None:
    """The one Part of a plain ASCII STL's bytes `data` (module docstring), as trimesh's reader gives it (float64
    corners in file order, faces 0 1 2, 3 4 5, ...); None for any other text (trimesh's)."""
    first = data.lstrip().split(b"\n", 1)[0].lower()
    if b"vertex" in first or b"endsolid" in first:  # a name trimesh's split would take apart
        return None
    text = np.frombuffer(data, np.uint8)
    no_points, no_text = np.empty((0, 3)), np.empty(0, np.uint8)
    plain, corners, size, _ = _facets(text, 0, WORDS, LENGTHS, POWERS, no_points, no_text)
    if not plain:
        return None
    points = np.empty((corners, 3))
    if not _facets(text, 1, WORDS, LENGTHS, POWERS, points, no_text)[3]:
        vertex_text = np.empty(size, np.uint8)
        _facets(text, 2, WORDS, LENGTHS, POWERS, no_points, vertex_text)
        points = numpy_rows(vertex_text.tobytes(), corners, 3)
        if points is None:
            return None
    return Part(points, np.arange(corners, dtype=np.int64).reshape(-1, 3), None, None)


def warm_up() -> None:
    """Load (or compile) _facets: a plain triangle, counted and read."""
    plain_stl(b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\r\nvertex 0 1 0\nendloop\n"
              b"endfacet\nendsolid t\n")
