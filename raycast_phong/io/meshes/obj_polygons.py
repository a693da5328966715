"""An OBJ's polygons of four or more corners that are not convex, cut into triangles by ear clipping.

trimesh cuts every polygon as a fan from its first corner, which is right only for a convex polygon: a
concave one (a ring exported as one face with a bridge, an L-shaped panel) becomes triangles that cover
what the polygon leaves open. Here the OBJ text is rewritten before trimesh reads it: each concave
polygon's `f` line becomes one `f` line per triangle, cut by mapbox-earcut (which trimesh itself uses for
2-D polygons) in the polygon's own plane, each corner keeping its `v/vt/vn` token. Convex polygons and
triangles are left to trimesh's fan, which is the same for them. Only files with such polygons pay.

The text is read once by a compiled scan (`_scan`: its lines, `v` and `f` records, the vertex number of each
corner), so a file of a million quads costs a pass over its bytes and a vectorised convexity test, not a
Python object per token. Lines end in LF or CRLF.

Before that, relative face indices are made absolute (`absolute_indices`): `f -4 -3 -2 -1` names the four
`v` lines above it (the OBJ specification), but trimesh counts a negative index back from the file's last
vertex, so a file that defines each face after its own vertices (a Cornell box) collapsed onto its last
quad. Index 0, which names nothing (indices start at 1), is found in the same pass and refused.
"""

from __future__ import annotations

import numpy as np

from ...jit import kernel
from .decimals import line_end
from .polygons import ear_clip

SPACE, TAB, LF, CR, HASH, SLASH, MINUS, PLUS, ZERO = 32, 9, 10, 13, 35, 47, 45, 43, 48
OBJ_KERNELS = ("_absolute", "_scan", "_concave")  # what reading an OBJ compiles (renderer/warmup.py loads them first)


@kernel(inline="always")
def _blank(c):
    """Space or tab: what separates an OBJ record's words."""
    return c == SPACE or c == TAB


@kernel(inline="always")
def _white(c):
    """Any whitespace byte (space, tab, LF, CR, FF, VT): where a coordinate word ends."""
    return c == SPACE or c == TAB or c == LF or c == CR or c == 12 or c == 11


INDEX_KINDS = ("v", "vt", "vn")  # what the components of a face corner `v/vt/vn` count


@kernel(inline="always")
def _digits(value):
    """How many decimal digits a positive integer has."""
    count = 1
    while value >= 10:
        value //= 10
        count += 1
    return count


@kernel(inline="always")
def _copy(out, written, data, start, end):
    """data[start:end] into out from `written` on; returns the new end of out's text (a loop, not a slice
    assignment: numba compiles the latter's shape-mismatch message, 1.5 s of the reader's first compile)."""
    for k in range(start, end):
        out[written] = data[k]
        written += 1
    return written


@kernel()
def _absolute(data):
    """OBJ text `data` (uint8) with every relative (negative) face index made absolute, in two passes (find and
    measure, then write). Returns (text, changed, problem, line, kind, value, above): problem 0 none, 1 an
    index 0, 2 a relative index past the first record of its kind; line (1-based) of the face, kind
    (INDEX_KINDS), value of the first such index and how many records of its kind are above the face; `text`
    is empty when nothing changed or on a problem.

    Records: blanks, a keyword, a blank; a backslash before the line's end continues the record on the next
    line (trimesh joins such lines too). `v`, `vt` and `vn` records are counted; in an `f` record each corner's
    `/`-separated components that are integers ([+-]digits) are checked, a negative one -k replaced by the
    count of its kind above the record minus k plus 1. A `#` ends the record's words."""
    n = data.shape[0]
    out = np.empty(0, np.uint8)
    size = n
    changed = False
    for fill in range(2):
        if fill:
            if not changed:
                return out, False, 0, 0, 0, 0, 0
            out = np.empty(size, np.uint8)
        counts = np.zeros(3, np.int64)
        size, copied, written, line, at = n, 0, 0, 1, 0
        while at < n:
            first_line = line
            i = at
            while i < n and _blank(data[i]):
                i += 1
            start = i
            while i < n and not _white(data[i]):
                i += 1
            keyword = i - start
            kind = -1
            if keyword == 1 and data[start] == 118:  # v
                kind = 0
            elif keyword == 2 and data[start] == 118 and data[start + 1] == 116:  # vt
                kind = 1
            elif keyword == 2 and data[start] == 118 and data[start + 1] == 110:  # vn
                kind = 2
            face = keyword == 1 and data[start] == 102 and i < n and _blank(data[i])  # f and a blank
            if kind >= 0 and i < n and _blank(data[i]):
                counts[kind] += 1
            # the record runs to an LF not continued by a backslash (before it, or before its CR)
            comment = False
            while i < n:
                c = data[i]
                if c == LF:
                    line += 1
                    if (i >= 1 and data[i - 1] == 92) or (i >= 2 and data[i - 1] == CR and data[i - 2] == 92):
                        i += 1
                        continue
                    break
                if c == HASH:
                    comment = True
                if not face or comment or _white(c) or c == 92:
                    i += 1
                    continue
                # a corner: its components, each up to a `/`, the corner ending at whitespace, `#` or `\`
                component = 0
                while i < n and not _white(data[i]) and data[i] != HASH and data[i] != 92:
                    k = i
                    sign = 1
                    if data[k] == MINUS or data[k] == PLUS:
                        sign = -1 if data[k] == MINUS else 1
                        k += 1
                    value, digits = 0, 0
                    while k < n and ZERO <= data[k] <= ZERO + 9 and digits < 18:
                        value, digits = 10 * value + (data[k] - ZERO), digits + 1
                        k += 1
                    end = k
                    while end < n and not _white(data[end]) and data[end] != SLASH and data[end] != HASH \
                            and data[end] != 92:
                        end += 1
                    if digits and end == k and component < 3:  # an integer component
                        if value == 0:
                            return out, False, 1, first_line, component, 0, counts[component]
                        if sign < 0:
                            absolute = counts[component] - value + 1
                            if absolute < 1:
                                return out, False, 2, first_line, component, -value, counts[component]
                            if fill:
                                written = _copy(out, written, data, copied, i)
                                places = _digits(absolute)
                                for d in range(places):
                                    out[written + places - 1 - d] = ZERO + absolute % 10
                                    absolute //= 10
                                written += places
                                copied = end
                            else:
                                size += _digits(absolute) - (end - i)
                                changed = True
                    i = end
                    if i < n and data[i] == SLASH:
                        i += 1
                        component += 1
            at = i + 1
        if fill:
            _copy(out, written, data, copied, n)
    return out, True, 0, 0, 0, 0, 0


def absolute_indices(data: bytes) -> tuple[bytes, str | None]:
    """The OBJ text with relative face indices made absolute (_absolute), and None; or the text unchanged and
    what is wrong ("line 7: index 0 (`vt`) ..."), for the reader's one-line error."""
    if b"f" not in data:
        return data, None
    text, changed, problem, line, kind, value, above = _absolute(np.frombuffer(data, np.uint8))
    name = INDEX_KINDS[kind]
    allowed = f"allowed: 1, 2, ... (the file's `{name}` lines in order) or -1, -2, ... (back from the face)"
    if problem == 1:
        return data, f"line {line}: face index 0 (`{name}`) names nothing; {allowed}"
    if problem == 2:
        return data, (f"line {line}: face index {value} (`{name}`) counts back past the first `{name}` line "
                      f"({above} `{name}` line{'' if above == 1 else 's'} above it); {allowed}")
    return (text.tobytes() if changed else data), None


@kernel()
def _scan(data):
    """The `v` and polygon `f` records of OBJ text `data` (uint8), in two passes (count, then fill).

    A `v` line: blanks, `v`, then three words (any non-whitespace) separated by blanks; its words' byte spans go
    to points (V, 3, 2). A polygon: blanks, `f`, four or more words (no blank, CR or `#` in them) each after
    blanks, then blanks and an optional `#` comment to the line's end (LF, or CRLF). Per polygon: line (P, 2) the
    span to replace (its comment included, its CR not), first and count into the words, before the `v` lines
    above it (a negative index counts back from there), whole whether every word starts with an integer
    ([+-]digits, up to its `/`). Per word: word (W, 2) its span, index (W,) that integer."""
    n = data.shape[0]
    points = np.empty((0, 3, 2), np.int64)
    line = np.empty((0, 2), np.int64)
    first = np.empty(0, np.int64)
    count = np.empty(0, np.int64)
    before = np.empty(0, np.int64)
    whole = np.empty(0, np.bool_)
    word = np.empty((0, 2), np.int64)
    index = np.empty(0, np.int64)
    vertices = polygons = words = 0
    for fill in range(2):
        if fill:
            points = np.empty((vertices, 3, 2), np.int64)
            line = np.empty((polygons, 2), np.int64)
            first, count = np.empty(polygons, np.int64), np.empty(polygons, np.int64)
            before = np.empty(polygons, np.int64)
            whole = np.empty(polygons, np.bool_)
            word, index = np.empty((words, 2), np.int64), np.empty(words, np.int64)
        vertices = polygons = words = 0
        at = 0
        while at < n:
            end, stop = line_end(data, at)  # a CRLF line ends before its CR
            i = at
            while i < stop and _blank(data[i]):
                i += 1
            if i + 1 < stop and data[i] == 118 and _blank(data[i + 1]):  # "v" and a blank
                j, found = i + 1, 0
                while found < 3:
                    blanks = j
                    while j < stop and _blank(data[j]):
                        j += 1
                    if j == blanks or j == stop or _white(data[j]):
                        break
                    start = j
                    while j < stop and not _white(data[j]):
                        j += 1
                    if fill and vertices < points.shape[0]:  # a line that proves no vertex is overwritten
                        points[vertices, found, 0], points[vertices, found, 1] = start, j
                    found += 1
                if found == 3:
                    vertices += 1
            elif i + 1 < stop and data[i] == 102 and _blank(data[i + 1]):  # "f" and a blank
                j, found, valid, integers = i + 1, 0, True, True
                while True:
                    blanks = j
                    while j < stop and _blank(data[j]):
                        j += 1
                    if j == stop or data[j] == HASH:
                        break  # the end, or a comment to the end
                    if j == blanks or data[j] == CR:  # a word without a blank before it, or a bare CR
                        valid = False
                        break
                    start = j
                    while j < stop and not _blank(data[j]) and data[j] != CR and data[j] != HASH:
                        j += 1
                    if fill and words + found < word.shape[0]:  # a line that proves no polygon is overwritten
                        word[words + found, 0], word[words + found, 1] = start, j
                        k, sign, value, digits = start, 1, 0, 0
                        if data[k] == MINUS or data[k] == PLUS:
                            sign = -1 if data[k] == MINUS else 1
                            k += 1
                        while k < j and ZERO <= data[k] <= ZERO + 9 and digits < 18:
                            value, digits = 10 * value + (data[k] - ZERO), digits + 1
                            k += 1
                        if digits == 0 or (k < j and data[k] != SLASH):
                            integers = False
                        index[words + found] = sign * value
                    found += 1
                if valid and found >= 4:
                    if fill:
                        line[polygons, 0], line[polygons, 1] = at, stop
                        first[polygons], count[polygons], before[polygons] = words, found, vertices
                        whole[polygons] = integers
                    polygons += 1
                    words += found
            at = end + 1
    return points, line, first, count, before, whole, word, index


@kernel()
def _number(data, start, end):
    """The decimal number data[start:end] ([+-]digits[.digits][(e|E)[+-]digits]), or NaN if it is not one.

    Its first 18 significant digits times a power of ten: within a few units in the last place of the correctly
    rounded value (between 1e-300 and 1e300; a value within a few units of the largest float may overflow), which
    the convexity test's tolerance (1e-12 of a polygon's largest turn) absorbs; trimesh reads the coordinates the
    render uses."""
    k, sign = start, 1.0
    if k < end and (data[k] == MINUS or data[k] == PLUS):
        sign = -1.0 if data[k] == MINUS else 1.0
        k += 1
    mantissa, significant, exponent, digits = 0, 0, 0, 0
    point = False
    while k < end:
        c = data[k]
        if c == 46 and not point:  # "."
            point = True
        elif ZERO <= c <= ZERO + 9:
            digits += 1
            if significant < 18:
                mantissa = 10 * mantissa + (c - ZERO)
                significant += 1 if mantissa > 0 else 0
                exponent -= 1 if point else 0
            elif not point:
                exponent += 1  # a digit past the 18th before the point: one more power of ten
        else:
            break
        k += 1
    if digits == 0:
        return np.nan
    if k < end and (data[k] == 101 or data[k] == 69):  # "e" or "E"
        k += 1
        power, negative, seen = 0, False, False
        if k < end and (data[k] == MINUS or data[k] == PLUS):
            negative = data[k] == MINUS
            k += 1
        while k < end and ZERO <= data[k] <= ZERO + 9:
            power = min(10 * power + (data[k] - ZERO), 100000)
            seen = True
            k += 1
        if not seen:
            return np.nan
        exponent += -power if negative else power
    if k != end:
        return np.nan
    value = sign * mantissa
    if exponent >= 0:
        return value * 10.0 ** min(exponent, 400)
    if exponent < -300:  # in two steps, so that 10^-exponent itself stays finite down to the subnormals
        value, exponent = value / 1e300, exponent + 300
    return value / 10.0 ** min(-exponent, 400)


@kernel()
def _concave(data, points, first, count, before, whole, index):
    """(P,) bool: which polygons are concave. A polygon is tested when its corners are integers naming vertices
    (1-based, or negative: back from the `v` lines above it) with numbers for coordinates: it is convex when it
    turns the same way at every corner about its own normal (Newell's: the sum of the cross products about the
    centre), turn_i = (e_i × e_i+1) · n ≥ −1e-12 max |turn|, e_i = c_i+1 − c_i, or has no normal."""
    position = np.empty((points.shape[0], 3))
    for v in range(points.shape[0]):
        for axis in range(3):
            position[v, axis] = _number(data, points[v, axis, 0], points[v, axis, 1])
    concave = np.zeros(first.shape[0], np.bool_)
    most = 0
    for p in range(first.shape[0]):
        most = max(most, count[p])
    corner = np.empty((most, 3))
    turn = np.empty(most)
    for p in range(first.shape[0]):
        n = count[p]
        usable = whole[p]
        for i in range(n):
            if not usable:
                break
            vertex = index[first[p] + i]
            vertex = before[p] + vertex if vertex < 0 else vertex - 1
            if vertex < 0 or vertex >= points.shape[0]:
                usable = False
                break
            for axis in range(3):
                corner[i, axis] = position[vertex, axis]
                usable = usable and np.isfinite(corner[i, axis])
        if not usable:
            continue  # left to the reader, which reports a bad corner or fans it
        cx = cy = cz = 0.0
        for i in range(n):
            cx, cy, cz = cx + corner[i, 0], cy + corner[i, 1], cz + corner[i, 2]
        cx, cy, cz = cx / n, cy / n, cz / n
        nx = ny = nz = 0.0
        for i in range(n):
            j = (i + 1) % n
            ax, ay, az = corner[i, 0] - cx, corner[i, 1] - cy, corner[i, 2] - cz
            bx, by, bz = corner[j, 0] - cx, corner[j, 1] - cy, corner[j, 2] - cz
            nx, ny, nz = nx + ay * bz - az * by, ny + az * bx - ax * bz, nz + ax * by - ay * bx
        if not nx * nx + ny * ny + nz * nz > 0:
            continue  # no normal: no side to turn to
        scale = 0.0
        for i in range(n):
            j, k = (i + 1) % n, (i + 2) % n
            ax, ay, az = corner[j, 0] - corner[i, 0], corner[j, 1] - corner[i, 1], corner[j, 2] - corner[i, 2]
            bx, by, bz = corner[k, 0] - corner[j, 0], corner[k, 1] - corner[j, 1], corner[k, 2] - corner[j, 2]
            turn[i] = (ay * bz - az * by) * nx + (az * bx - ax * bz) * ny + (ax * by - ay * bx) * nz
            scale = max(scale, abs(turn[i]))
        for i in range(n):
            if turn[i] < -1e-12 * scale:
                concave[p] = True
                break
    return position, concave


def triangulate_concave(data: bytes) -> tuple[bytes, int]:
    """The OBJ text with every concave polygon cut into triangles, and how many polygons were cut.

    One compiled pass reads the text's records (_scan) and one tests every polygon (_concave); only the concave
    ones are cut, one by one. A polygon with a corner that is not an integer naming a vertex, or a vertex whose
    coordinates are not numbers, is left to the reader, which reports it (or fans it)."""
    if b"f" not in data:
        return data, 0
    text = np.frombuffer(data, np.uint8)
    points, line, first, count, before, whole, word, index = _scan(text)
    if not len(line):
        return data, 0
    position, concave = _concave(text, points, first, count, before, whole, index)
    pieces, at, cut = [], 0, 0
    for k in np.flatnonzero(concave).tolist():
        corner = index[first[k]:first[k] + count[k]]
        triangles = ear_clip(position[np.where(corner < 0, before[k] + corner, corner - 1)])
        if triangles is None:
            continue
        tokens = [data[start:end] for start, end in word[first[k]:first[k] + count[k]].tolist()]
        lines = b"\n".join(b"f " + b" ".join(tokens[c] for c in triangle) for triangle in triangles)
        pieces += [data[at:line[k, 0]], lines]
        at, cut = int(line[k, 1]), cut + 1
    if not cut:
        return data, 0
    pieces.append(data[at:])
    return b"".join(pieces), cut


def warm_up() -> None:
    """Load (or compile) OBJ_KERNELS: a concave pentagon with relative indices, made absolute and cut."""
    triangulate_concave(absolute_indices(b"v 0 0 0\nv 2 0 0\nv 2 2 0\nv 1 0.5 0\nv 0 2 0\nf -5 -4 -3 -2 -1\n")[0])

