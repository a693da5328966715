"""Mesh preparation's compiled passes: face normals, per-vertex normal sums and corner gathers, the half-edge
check and orientation, the duplicate-vertex merge. Each is one pass over the faces (or vertices) with no
(3F,) temporaries, and does the arithmetic of the numpy code it replaced in the same order, so its results
carry the same bits (tests/geometry/test_prep_kernels.py compares them with that code).

Half-edges are bucketed by their lower vertex (a counting sort: linear, and each bucket holds a vertex's few
edges), in place of a sort of all 3F half-edge keys; points are merged through an open-addressing hash table.

Passes that may run on several threads (normals.run_parts: each thread calls the same kernel, which releases the
GIL) take either slices of the faces (face normals, corner gather, renumbering) or a range [low, high) of vertices
that they alone write (vertex sums, crease tests, half-edge buckets): each vertex's sum is still added in corner
order, so any split gives the bits of one thread.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import kernel

SMALL_BUCKET = 32  # half-edges at one vertex sorted by insertion below this, by a merge sort above


@kernel()
def face_normals_into(vertices, faces, unit, doubled_area):
    """unit (F, 3) zeroed by the caller: the unit normal of each face, zero where it is degenerate (or NaN);
    doubled_area (F,): |e1 × e2|. The products and sums of normals.cross_rows, in its order."""
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        e1x, e1y, e1z = (vertices[b, 0] - vertices[a, 0], vertices[b, 1] - vertices[a, 1],
                         vertices[b, 2] - vertices[a, 2])
        e2x, e2y, e2z = (vertices[c, 0] - vertices[a, 0], vertices[c, 1] - vertices[a, 1],
                         vertices[c, 2] - vertices[a, 2])
        cx = e1y * e2z - e1z * e2y
        cy = e1z * e2x - e1x * e2z
        cz = e1x * e2y - e1y * e2x
        area = math.sqrt(cx * cx + cy * cy + cz * cz)
        doubled_area[f] = area
        if area > 0:
            unit[f, 0], unit[f, 1], unit[f, 2] = cx / area, cy / area, cz / area


@kernel()
def vertex_normal_sums(faces, unit, weights, weighted, summed, low, high):
    """summed (V, 4) float64, zeroed by the caller: for each vertex v in [low, high), Σ w n_f (columns 0-2) and
    Σ w |n_f| (column 3) over its corners, added in corner order (3f + k) as np.bincount adds them; w =
    weights[f, k] if `weighted`, else 1. Rows outside the range are not touched (another thread's)."""
    for f in range(faces.shape[0]):
        for k in range(3):
            v = faces[f, k]
            if v < low or v >= high:
                continue
            u0, u1, u2 = unit[f, 0], unit[f, 1], unit[f, 2]
            length = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
            if weighted:
                w = weights[f, k]
                summed[v, 0] += w * u0
                summed[v, 1] += w * u1
                summed[v, 2] += w * u2
                summed[v, 3] += w * length
            else:
                summed[v, 0] += u0
                summed[v, 1] += u1
                summed[v, 2] += u2
                summed[v, 3] += length


@kernel()
def normalise_sums(summed, no_direction, normal, vague):
    """Into normal (V, 3) float64 and vague (V,) bool, for normal sums (V, 4) (any rows, with the outputs' same
    rows): the vertex normals, and which have no direction: |s| at most no_direction × the length they would
    have if every normal agreed (then the normal is left unscaled)."""
    for v in range(summed.shape[0]):
        s0, s1, s2 = summed[v, 0], summed[v, 1], summed[v, 2]
        size = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        vague[v] = size <= no_direction * summed[v, 3]
        if vague[v]:
            size = 1.0
        normal[v, 0], normal[v, 1], normal[v, 2] = s0 / size, s1 / size, s2 / size


@kernel()
def gather_corners(vertex_normal, vague, faces, unit, corners):
    """corners (F, 3, 3) in its dtype: each corner its vertex's normal, or its face's normal where the vertex is
    vague (its normal has no direction)."""
    for f in range(faces.shape[0]):
        for k in range(3):
            v = faces[f, k]
            for i in range(3):
                corners[f, k, i] = unit[f, i] if vague[v] else vertex_normal[v, i]


@kernel()
def count_half_edges(faces, start, low, high):
    """The first half of bucketing the half-edges by their lower vertex (a counting sort): start[v + 1] += the
    number of half-edges h = 3f + k (corner k → k + 1 of face f) whose lower vertex v is in [low, high). start
    (V + 1,) int64 zeroed by the caller, who then takes its running sum (bucket v is start[v]:start[v + 1])."""
    for f in range(faces.shape[0]):
        for k in range(3):
            v = min(faces[f, k], faces[f, (k + 1) % 3])
            if low <= v < high:
                start[v + 1] += 1


@kernel()
def bucket_half_edges(faces, start, key, edge, low, high):
    """The second half: fills the buckets of the vertices in [low, high) of key (3F,) and edge (3F,) (the caller's,
    int32 when they fit: 8 bytes a half-edge, not 16), and returns (consistent, closed, flippable) of those buckets.
    Bucket v is sorted by key = 2 × higher vertex + (1 where the half-edge runs high → low) and, among equal keys,
    by h = edge: the order a stable sort of all 3F (undirected edge, direction) keys gives. consistent: no
    half-edge is traversed twice in the same direction; closed: every undirected edge belongs to exactly two;
    flippable: some edge of exactly two faces is run the same way by both (the only edges orient_pieces asks a
    flip for: a mesh inconsistent only at edges of one or three or more faces has nothing a flip would mend)."""
    fill = start[low:high].copy()
    for f in range(faces.shape[0]):
        for k in range(3):
            a, b = faces[f, k], faces[f, (k + 1) % 3]
            v = min(a, b)
            if v < low or v >= high:
                continue
            at = fill[v - low]
            fill[v - low] += 1
            key[at] = 2 * max(a, b) + (1 if b < a else 0)
            edge[at] = 3 * f + k
    consistent, closed, flippable = True, True, False
    for v in range(low, high):
        first, last = start[v], start[v + 1]
        if last - first <= SMALL_BUCKET:
            for i in range(first + 1, last):  # insertion sort: stable
                k, e, j = key[i], edge[i], i - 1
                while j >= first and key[j] > k:
                    key[j + 1], edge[j + 1] = key[j], edge[j]
                    j -= 1
                key[j + 1], edge[j + 1] = k, e
        else:
            order = np.argsort(key[first:last], kind="mergesort")  # stable
            keys, edges = key[first:last][order], edge[first:last][order]
            for i in range(last - first):  # not a slice assignment: its shape check's message compiles in 2.5 s
                key[first + i], edge[first + i] = keys[i], edges[i]
        at = first
        while at < last:
            run = at + 1
            while run < last and key[run] >> 1 == key[at] >> 1:
                run += 1
            if run - at != 2:
                closed = False
            elif key[at] == key[at + 1]:
                flippable = True
            for i in range(at + 1, run):
                if key[i] == key[i - 1]:
                    consistent = False
            at = run
    return consistent, closed, flippable


@kernel()
def _root(parent, parity, x):
    """(root of x, x's side relative to it: 0 the same, 1 flipped), halving the path on the way (x's parent
    becomes its grandparent, its side then taken relative to the grandparent)."""
    side = 0
    while parent[x] != x:
        up = parent[x]
        parity[x] ^= parity[up]
        parent[x] = parent[up]
        side ^= parity[x]
        x = parent[x]
    return x, side


@kernel()
def orient_pieces(start, key, edge, face_count):
    """Orientation as a two-colouring of the faces: an edge shared by exactly two half-edges says its faces (f, g)
    keep the same side if the half-edges run opposite ways, else opposite sides (union-find with each face's side
    relative to its parent; each piece rooted at its least face, as scipy's connected_components numbers them;
    a cycle of constraints that disagree marks the piece non-orientable, e.g. a Möbius strip).
    Returns flip (F,) bool: per piece the side most faces already have (a tie keeps them as they are); piece (F,),
    the piece's least face (edge's dtype); orientable (F,) bool, False on a non-orientable piece."""
    parent = np.arange(face_count).astype(edge.dtype)  # face numbers < 3F fit edge's dtype
    parity = np.zeros(face_count, np.uint8)
    twisted = np.zeros(face_count, np.bool_)  # at a root: its piece cannot be oriented
    for v in range(start.shape[0] - 1):
        at, last = start[v], start[v + 1]
        while at < last:
            run = at + 1
            while run < last and key[run] >> 1 == key[at] >> 1:
                run += 1
            if run - at == 2:
                # Opposite directions: the faces agree as they are (0); the same direction: one must flip (1).
                apart = 0 if (key[at] & 1) != (key[at + 1] & 1) else 1
                a, side_a = _root(parent, parity, edge[at] // 3)
                b, side_b = _root(parent, parity, edge[at + 1] // 3)
                if a == b:
                    if side_a ^ side_b != apart:
                        twisted[a] = True
                elif a < b:
                    parent[b], parity[b] = a, side_a ^ side_b ^ apart
                    twisted[a] |= twisted[b]
                else:
                    parent[a], parity[a] = b, side_a ^ side_b ^ apart
                    twisted[b] |= twisted[a]
            at = run
    piece = np.empty(face_count, edge.dtype)
    as_is = np.empty(face_count, np.bool_)  # the face as it is has its piece's least face's side
    orientable = np.empty(face_count, np.bool_)
    votes = np.zeros(face_count, edge.dtype)
    for f in range(face_count):
        root, side = _root(parent, parity, f)
        piece[f], orientable[f] = root, not twisted[root]
        as_is[f] = side == 0 or twisted[root]
        votes[root] += 1 if as_is[f] else -1
    flip = np.empty(face_count, np.bool_)
    for f in range(face_count):
        flip[f] = orientable[f] and (as_is[f] != (votes[piece[f]] >= 0))
    return flip, piece, orientable


@kernel()
def signed_volume(vertices, faces, centre):
    """(Σ_f v0 · (v1 × v2), Σ_f of the absolute values of every product in it) about `centre`: six times the
    enclosed volume, and the scale its rounding error is measured against (mesh_repair._volume_sign)."""
    total, scale = 0.0, 0.0
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        x0, y0, z0 = vertices[a, 0] - centre[0], vertices[a, 1] - centre[1], vertices[a, 2] - centre[2]
        x1, y1, z1 = vertices[b, 0] - centre[0], vertices[b, 1] - centre[1], vertices[b, 2] - centre[2]
        x2, y2, z2 = vertices[c, 0] - centre[0], vertices[c, 1] - centre[1], vertices[c, 2] - centre[2]
        total += x0 * (y1 * z2 - z1 * y2) + y0 * (z1 * x2 - x1 * z2) + z0 * (x1 * y2 - y1 * x2)
        scale += ((abs(x0) + abs(y0) + abs(z0)) * (abs(x1) + abs(y1) + abs(z1)) * (abs(x2) + abs(y2) + abs(z2)))
    return total, scale


@kernel()
def merge_rows(rows, bits, used, table, new_of_old, first):
    """Rows (N, C) of float64 or float32 equal value by value (−0 = +0) merged, in row order. `bits`: the rows
    viewed as unsigned integers of their size (what is hashed). Fills new_of_old (N,) (−1 for a row not `used`)
    and first[:K], the first used row of each distinct value, numbered in the order first seen, and returns K.
    `table`: −1 everywhere, a power of two at least twice the used rows: an open-addressing hash table (linear
    probing) of splitmix64 over each row's bits. The hash decides only where a row is looked up, so the result
    is the same for any hash. The caller's arrays: int32 when N < 2^31."""
    n, width = rows.shape
    mask = np.uint64(table.shape[0] - 1)
    new_of_old[:] = -1
    count = 0
    for i in range(n):
        if not used[i]:
            continue
        h = np.uint64(0)
        for c in range(width):
            h ^= np.uint64(bits[i, c]) if rows[i, c] != 0.0 else np.uint64(0)  # −0.0 and +0.0: one value
            h ^= h >> np.uint64(30)
            h *= np.uint64(0xBF58476D1CE4E5B9)
            h ^= h >> np.uint64(27)
            h *= np.uint64(0x94D049BB133111EB)
            h ^= h >> np.uint64(31)
        slot = h & mask
        while True:
            j = table[slot]
            if j < 0:
                table[slot] = i
                new_of_old[i] = count
                first[count] = i
                count += 1
                break
            same = True
            for c in range(width):
                if rows[i, c] != rows[j, c]:
                    same = False
                    break
            if same:
                new_of_old[i] = new_of_old[j]
                break
            slot = (slot + np.uint64(1)) & mask
    return count


@kernel()
def renumber(faces, new_of_old, out):
    """out (F, 3) int64 := new_of_old[faces] (any rows of both)."""
    for f in range(faces.shape[0]):
        for k in range(3):
            out[f, k] = new_of_old[faces[f, k]]


@kernel()
def first_use_numbers(faces, new_of_old, first, out):
    """Vertices numbered in the order the faces first use them (corner order 3f + k): out (F, 3) := the new number
    of each corner's vertex; new_of_old (V,) the caller's, -1 everywhere, gets each used vertex's new number, and
    first[:K] each new number's old vertex. Returns K, the vertices used."""
    count = 0
    for f in range(faces.shape[0]):
        for k in range(3):
            old = faces[f, k]
            new = new_of_old[old]
            if new < 0:
                new = count
                new_of_old[old] = new
                first[new] = old
                count += 1
            out[f, k] = new
    return count


@kernel()
def gather_corners_creased(vertex_normal, vague, faces, unit, least, corners, apart):
    """gather_corners, and in the same pass the crease test of normals._creased_vertices' rule: apart (V,) bool
    (the caller's, False) is set at each vertex with a corner whose face normal n_f has a cosine with the vertex
    normal below `least` (or NaN), its products added in that rule's order. Any rows of faces, unit and corners
    (a thread's slice); each thread its own `apart`, OR-ed by the caller (with the vague vertices: the split)."""
    for f in range(faces.shape[0]):
        for k in range(3):
            v = faces[f, k]
            for i in range(3):
                corners[f, k, i] = unit[f, i] if vague[v] else vertex_normal[v, i]
            cosine = 0.0
            cosine += unit[f, 0] * vertex_normal[v, 0]
            cosine += unit[f, 1] * vertex_normal[v, 1]
            cosine += unit[f, 2] * vertex_normal[v, 2]
            if not cosine >= least:  # NaN too
                apart[v] = True


@kernel()
def creased_corners(faces, unit, weights, weighted, split, least, no_direction, corners, low, high):
    """Corner normals (into corners (F, 3, 3)) at the vertices in [low, high) that `split` marks: each corner sums
    w n_g and w |n_g| over the corners at its vertex (in corner order) whose face g is within the crease of its
    own (n_f · n_g ≥ `least`), then normalises, or takes n_f where the sum has no direction
    (normals._creased_sums and _normalise_or, their additions in their order). The corners are bucketed by
    vertex (a counting sort over the range's vertices)."""
    count = high - low
    start = np.zeros(count + 1, np.int64)
    for f in range(faces.shape[0]):
        for k in range(3):
            v = faces[f, k]
            if low <= v < high and split[v]:
                start[v - low + 1] += 1
    for v in range(count):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    corner = np.empty(start[count], np.int64)
    for f in range(faces.shape[0]):
        for k in range(3):
            v = faces[f, k]
            if low <= v < high and split[v]:
                corner[fill[v - low]] = 3 * f + k
                fill[v - low] += 1
    for v in range(count):
        for at in range(start[v], start[v + 1]):
            f, k = corner[at] // 3, corner[at] % 3
            s0, s1, s2, reach = 0.0, 0.0, 0.0, 0.0
            for other in range(start[v], start[v + 1]):
                g, j = corner[other] // 3, corner[other] % 3
                cosine = unit[f, 0] * unit[g, 0] + unit[f, 1] * unit[g, 1] + unit[f, 2] * unit[g, 2]
                if cosine >= least:
                    w = weights[g, j] if weighted else 1.0
                    length = math.sqrt(unit[g, 0] * unit[g, 0] + unit[g, 1] * unit[g, 1] + unit[g, 2] * unit[g, 2])
                    if weighted:
                        s0 += w * unit[g, 0]
                        s1 += w * unit[g, 1]
                        s2 += w * unit[g, 2]
                        reach += w * length
                    else:
                        s0 += unit[g, 0]
                        s1 += unit[g, 1]
                        s2 += unit[g, 2]
                        reach += length
            size = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
            if size <= no_direction * reach:
                corners[f, k, 0], corners[f, k, 1], corners[f, k, 2] = unit[f, 0], unit[f, 1], unit[f, 2]
            else:
                corners[f, k, 0], corners[f, k, 1], corners[f, k, 2] = s0 / size, s1 / size, s2 / size


@kernel()
def object_bounds(vertices, faces, face_object, centre, radius):
    """Each object's bounding-box centre (into centre (N, 3)) and the largest distance of its vertices from it
    (into radius (N,)), over the vertices its faces use (objects own disjoint vertices); both zeroed by the
    caller, and left so for an object without faces. The numbers of diagnosis' numpy code (min and max per
    coordinate, then √(dx² + dy² + dz²) added in that order), in three passes and no (V, 3) temporaries."""
    objects = centre.shape[0]
    owner = np.full(vertices.shape[0], -1, np.int64)
    for f in range(faces.shape[0]):
        for k in range(3):
            owner[faces[f, k]] = face_object[f]
    low, high = np.empty((objects, 3)), np.empty((objects, 3))
    present = np.zeros(objects, np.bool_)
    for v in range(vertices.shape[0]):
        o = owner[v]
        if o < 0:
            continue
        for i in range(3):
            x = vertices[v, i]
            if not present[o] or x < low[o, i]:
                low[o, i] = x
            if not present[o] or x > high[o, i]:
                high[o, i] = x
        present[o] = True
    for o in range(objects):
        if present[o]:
            for i in range(3):
                centre[o, i] = (low[o, i] + high[o, i]) / 2
    for v in range(vertices.shape[0]):
        o = owner[v]
        if o < 0:
            continue
        dx, dy, dz = vertices[v, 0] - centre[o, 0], vertices[v, 1] - centre[o, 1], vertices[v, 2] - centre[o, 2]
        distance = math.sqrt(dx * dx + dy * dy + dz * dz)
        if distance > radius[o]:
            radius[o] = distance
