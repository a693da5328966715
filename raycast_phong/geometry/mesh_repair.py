"""Repair what a mesh file gets wrong for shading: points it repeats (merged) and faces wound inconsistently
(made consistent, and outward when the mesh is closed). Compiled passes over the raw arrays (kernels.py),
linear in the triangles (docs/performance.md, "Mesh files at millions of triangles").
"""

from __future__ import annotations

import math

import numpy as np

from ..records import bounding_box
from .kernels import (
    bucket_half_edges,
    count_half_edges,
    first_use_numbers,
    merge_rows,
    orient_pieces,
    renumber,
    signed_volume,
)
from .normals import FACE_CHUNK, cross_rows, parts, run_parts


def repair_winding(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, int, bool]:
    """Make a mesh file's winding consistent, and outward if the mesh is closed.

    Inconsistent winding makes face normals of neighbours cancel in the vertex-normal mean. Returns
    the faces, how many were flipped, and whether the mesh is closed (every edge in exactly two faces:
    then it is turned outward, by its signed volume). A consistent mesh, the common case, costs one
    pass bucketing its 3F half-edges by vertex (winding_state; and a closed one its signed volume,
    taken over the whole mesh as trimesh's fix_inversion did: a consistent mesh whose pieces disagree is left
    to its majority by volume); so does one inconsistent only at edges no flip mends (of one face, or of three
    or more: a real scan's holes and non-manifold seams). Only a mesh where two faces run their shared edge the same
    way pays for the face graph (kernels.orient_pieces: per piece the side most faces have), and if closed each
    piece is then turned outward by its own volume.
    """
    kind = np.int32 if len(vertices) < 1 << 30 and 3 * len(faces) < 1 << 31 else np.int64
    key, edge = np.empty(3 * len(faces), kind), np.empty(3 * len(faces), kind)
    consistent, closed, flippable, start = winding_state(faces, len(vertices), key, edge)
    if consistent or not flippable:  # not flippable: inconsistent only where no flip helps (then not closed)
        del start, key, edge
        if closed and _volume_sign(vertices, faces) < 0:
            return faces[:, ::-1], len(faces), True
        return faces, 0, closed
    flip, piece, orientable = orient_pieces(start, key, edge, len(faces))
    del start, key, edge
    if closed:  # each piece turned outward: the side of positive volume
        sign = np.where(flip, -1.0, 1.0)
        inward = _signed_volumes(vertices, faces, piece, len(faces), sign) < 0
        flip ^= orientable & inward[piece]
    flipped = int(flip.sum())
    if not flipped:
        return faces, 0, closed  # inconsistent only where no flip helps (a duplicate or non-manifold face)
    repaired = faces.copy()
    repaired[flip] = faces[flip, ::-1]
    return repaired, flipped, closed


def winding_state(faces: np.ndarray, vertex_count: int, key: np.ndarray, edge: np.ndarray):
    """(consistent, closed, flippable, start) of a mesh: consistent, no half-edge is traversed twice in the same
    direction; closed, every undirected edge belongs to exactly two half-edges; flippable, some edge of exactly two
    faces is run the same way by both (kernels.bucket_half_edges); start (V + 1,) the buckets of half-edges
    by lower vertex filled into key and edge (3F,) (kernels.count_half_edges, kernels.bucket_half_edges).
    Above PARALLEL_FACES each thread counts, fills and sorts the buckets of its own range of vertices."""
    start = np.zeros(vertex_count + 1, np.int64)
    run_parts(lambda low, high: count_half_edges(faces, start, low, high), parts(vertex_count, len(faces)))
    np.cumsum(start, out=start)
    states = run_parts(lambda low, high: bucket_half_edges(faces, start, key, edge, low, high),
                       parts(vertex_count, len(faces), lambda: start))  # cut at equal shares of the half-edges
    return (all(state[0] for state in states), all(state[1] for state in states), any(state[2] for state in states),
            start)


def _volume_sign(vertices: np.ndarray, faces: np.ndarray) -> float:
    """The sign of _signed_volumes(vertices, faces)[0] (−1, 0 or 1), from one compiled pass.

    The pass adds in another order than numpy, so its sum may differ in the last bits, but both lie within
    γ = (F + 5) u of the exact sum, relative to the sum of the absolute values of every product (`scale`:
    five roundings in a term, F − 1 in the sum, u = 2^-53). Beyond twice that from 0 both have the exact sum's
    sign; nearer (a closed mesh of almost no volume) the numpy sum decides."""
    low, high = bounding_box(vertices)
    total, scale = signed_volume(vertices, faces, (low + high) / 2)
    n = len(faces) + 5
    if abs(total) > 2.0 * n * 2.0 ** -53 / (1 - n * 2.0 ** -53) * scale:
        return math.copysign(1.0, total)
    return float(np.sign(_signed_volumes(vertices, faces)[0]))


def _signed_volumes(vertices: np.ndarray, faces: np.ndarray, piece: np.ndarray | None = None, pieces: int = 1,
                    sign: np.ndarray | float = 1.0) -> np.ndarray:
    """Six times the signed volume enclosed by each piece's faces (divergence theorem: Σ v0 · (v1 × v2)),
    (pieces,) float64; piece (F,) numbers each face's piece (None: one piece), `sign` (F,) −1 for a face
    taken flipped. Measured from the bounding-box centre, so a mesh far from the origin keeps its digits."""
    low, high = bounding_box(vertices)
    centred = vertices - (low + high) / 2
    sign = np.broadcast_to(sign, len(faces))
    total = np.zeros(pieces)
    for at in range(0, len(faces), FACE_CHUNK):
        part = faces[at:at + FACE_CHUNK]
        v0, v1, v2 = (centred[part[:, k]] for k in range(3))
        six = np.einsum("ij,ij->i", v0, cross_rows(v1, v2)) * sign[at:at + FACE_CHUNK]
        total += six.sum() if piece is None else np.bincount(piece[at:at + FACE_CHUNK], six, minlength=pieces)
    return total


def merge_duplicate_vertices(vertices: np.ndarray, faces: np.ndarray,
                             normals: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices at exactly the same position and drop those no face uses; the first of each kept, in file order.
    `vertices` (V, 3) float64, or float32 as a binary STL is read; the result is float64.

    What trimesh's process() did that matters for shading: a file that repeats a point for every face
    around it (STL always, OBJ and PLY often) must share it, or the vertex-normal mean sees one face
    and the surface shades faceted. As process(), vertices whose file normals (V, 3) differ (rounded to
    0.01) stay apart: a hard edge the file draws stays hard. Unlike process(): positions are compared
    exactly (−0 = +0), not rounded to trimesh's 1e-8 grid, and UV coordinates do not keep two vertices
    apart (the renderer reads no textures: a texture seam is no edge of the surface). Rows go through a
    hash table in file order (kernels.merge_rows, linear); a row that is not finite (a file normal of NaN)
    is merged by hashing and sorting the rows (_merge_sorted), which compares them as numpy does.
    """
    used = np.zeros(len(vertices), bool)
    used[faces] = True
    rows = vertices if normals is None else np.column_stack([vertices, np.round(normals * 100)])
    if normals is not None and not np.isfinite(rows[used]).all():
        return _merge_sorted(vertices, faces, normals, used)
    size = 1 << max(1, int(np.count_nonzero(used)) * 2 - 1).bit_length()  # a power of two ≥ 2 × the used rows
    kind = np.int32 if len(rows) < 1 << 31 else np.int64
    table, new_of_old, first = np.full(size, -1, kind), np.empty(len(rows), kind), np.empty(len(rows), kind)
    # float32 points (a binary STL's, as read) are compared as they are: the same equalities as in float64.
    rows = np.ascontiguousarray(rows, np.float32 if rows.dtype == np.float32 else np.float64)
    bits = rows.view(np.uint32 if rows.dtype == np.float32 else np.uint64)
    first = first[:merge_rows(rows, bits, used, table, new_of_old, first)]
    del table, rows, bits
    if len(first) == len(vertices):
        return np.asarray(vertices, np.float64), faces  # nothing to merge or drop: no copies (of float64)
    remapped = np.empty(faces.shape, np.int64)  # new_of_old[faces], one slice of the faces per thread
    run_parts(lambda low, high: renumber(faces[low:high], new_of_old, remapped[low:high]),
              parts(len(faces), len(faces)))
    return np.asarray(vertices[first], np.float64), remapped


# A mesh whose exactly merged vertices outnumber its faces this many times over is a soup: its triangles share
# no point (a closed surface has about half a vertex a face, a sheet with seams rarely more than one).
SOUP_VERTICES_PER_FACE = 1.5
# A soup's copies of a point are welded within this share of the model's largest extent: exporters that write each
# triangle alone round its corners apart (1e-12 of the size from float64 arithmetic, 1e-7 through float32), which
# the exact merge keeps apart, so the vertex normals saw one face each (faceted) and the winding could not be
# made consistent (normals facing away). trimesh merges within 1e-8 absolute; MeshLab's "merge close vertices"
# takes a share of the bounding box's diagonal, as this does.
WELD_SHARE = 1e-6


def weld_soup(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """A triangle soup's (SOUP_VERTICES_PER_FACE) vertices within WELD_SHARE of the model's size welded into one,
    the first of each group kept; returns the vertices, the faces and how many vertices went. Any other mesh is
    returned as it is, at no cost.

    Points are binned on a grid of that step eight times, the grid moved by half a step along each combination of
    axes, and grouped by the cell they share in any of them (repeated until no group grows): two points closer
    than half a step on every axis fall in one cell of at least one of the eight grids."""
    if len(vertices) <= SOUP_VERTICES_PER_FACE * len(faces) or not len(faces):
        return vertices, faces, 0
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    step = WELD_SHARE * float((high - low).max())
    if not step > 0:
        return vertices, faces, 0
    scaled = (vertices - low) / step
    label = np.arange(len(vertices))
    while True:
        before = label.copy()
        for offset in np.ndindex(2, 2, 2):
            cells = np.floor(scaled + 0.5 * np.asarray(offset)).astype(np.int64)  # ≤ 1e6 + 1: 21 bits each
            key = (cells[:, 0] << 42) | (cells[:, 1] << 21) | cells[:, 2]
            _, cell = np.unique(key, return_inverse=True)
            smallest = np.full(cell.max() + 1, len(vertices))
            np.minimum.at(smallest, cell, label)
            label = smallest[cell]
        label = label[label]  # a group's first vertex may itself have joined an earlier group
        if np.array_equal(label, before):
            break
    kept = np.flatnonzero(label == np.arange(len(vertices)))
    if len(kept) == len(vertices):
        return vertices, faces, 0
    number = np.full(len(vertices), -1, np.int64)
    number[kept] = np.arange(len(kept))
    return vertices[kept], number[label][faces], len(vertices) - len(kept)


def number_by_first_use(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mesh with its vertices numbered in the order its faces first use them (kernels.first_use_numbers; one
    pass), those no face uses dropped: the same surface, corner for corner, and the same faces in the same order.

    Every later pass over the faces (winding check, face and vertex normals, corner gathers, crease split, the BVH
    build) reads the vertices of neighbouring faces; a file whose vertex order wanders from its faces' (bunny-1m as
    make_scans.py writes it: the midpoints appended after the original points) sends each of them to memory at
    random. On bunny-1m's PLY: 20 ms for the pass, 50 ms of CPU less in those after (interleaved render_file A/B:
    CPU 0.93, GLB 0.85). A binary STL's merge numbers its points in this order already."""
    kind = np.int32 if len(vertices) < 1 << 31 else np.int64
    new_of_old, first = np.full(len(vertices), -1, kind), np.empty(len(vertices), kind)
    renumbered = np.empty(faces.shape, np.int64)
    count = first_use_numbers(faces, new_of_old, first, renumbered)
    return vertices[first[:count]], renumbered


def _merge_sorted(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray | None, used: np.ndarray):
    """merge_duplicate_vertices by sorting row hashes (V log V); equal hashes are then checked value by value.
    `used` (V,) bool: the vertices some face uses."""
    index = np.flatnonzero(used)
    rows = vertices[index] if normals is None else np.column_stack([vertices[index], np.round(normals[index] * 100)])
    rows += 0.0  # −0.0 + 0.0 is +0.0: the two zeros are one value
    key = _row_hashes(rows)
    order = np.argsort(key)
    key = key[order]
    starts = np.r_[True, key[1:] != key[:-1]]
    del key
    if starts.all():
        if len(index) == len(vertices):
            return vertices, faces
        first = np.arange(len(index))
    else:
        # The first row (in file order) of each run of equal keys stands for the run.
        first_sorted = np.minimum.reduceat(order, np.flatnonzero(starts))[np.cumsum(starts) - 1]
        # A run holds one row unless two rows collided in the hash (about 2^-64 per pair): then fall back
        # to numpy's exact (and slower) row comparison.
        if (rows[first_sorted] == rows[order]).all():
            first = np.empty_like(order)
            first[order] = first_sorted  # from sorted positions back to the rows' order
        else:
            _, first_seen, inverse = np.unique(rows, axis=0, return_index=True, return_inverse=True)
            first = first_seen[inverse.ravel()]
    # first[i]: the first vertex (in `index` order) at point i's position; number the firsts in order.
    keep = first == np.arange(len(first))
    number = np.cumsum(keep) - 1
    new_of_old = np.full(len(vertices), -1, np.int64)
    new_of_old[index] = number[first]
    return vertices[index[keep]], new_of_old[faces]


def _row_hashes(rows: np.ndarray) -> np.ndarray:
    """One uint64 per row of a float64 array (N, C): splitmix64's mixer over the columns in turn, so every
    input bit reaches every output bit (float32 data in float64 leaves the low 29 mantissa bits zero)."""
    bits = rows.view(np.uint64)
    key = np.zeros(len(rows), np.uint64)
    for column in range(bits.shape[1]):
        key ^= bits[:, column]
        key ^= key >> np.uint64(30)
        key *= np.uint64(0xBF58476D1CE4E5B9)
        key ^= key >> np.uint64(27)
        key *= np.uint64(0x94D049BB133111EB)
        key ^= key >> np.uint64(31)
    return key


# The compiled passes a mesh file's preparation calls (besides the normals' kernels every smooth object needs).
MESH_FILE_KERNELS = ("merge_rows", "renumber", "first_use_numbers", "count_half_edges", "bucket_half_edges",
                     "orient_pieces", "signed_volume")


def warm_up_merge() -> None:
    """The merge's and the renumbering's kernels: a tetrahedron that repeats a point, as float32 (a binary STL's
    points) and float64."""
    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    faces = np.array([[4, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    merge_duplicate_vertices(points.astype(np.float32), faces)
    vertices, faces = merge_duplicate_vertices(points, faces)
    number_by_first_use(vertices, faces)


def winding_signatures() -> dict:
    """The winding's kernels, each with the argument types repair_winding gives them (float64 vertices and centre,
    int64 faces and bucket starts, int32 keys and edges while they fit, int64 bounds and counts): compiled by
    signature, without running them, so that their compile can be shared out (split_compile.py: the helper
    compiles WINDING_KERNELS, the command the rest; warm_up_winding then loads them)."""
    from numba import typeof, types
    faces, start, key = typeof(np.zeros((1, 3), np.int64)), typeof(np.zeros(1, np.int64)), typeof(np.zeros(1, np.int32))
    return {count_half_edges: (faces, start, types.int64, types.int64),
            bucket_half_edges: (faces, start, key, key, types.int64, types.int64),
            orient_pieces: (start, key, key, types.int64),
            signed_volume: (typeof(np.zeros((1, 3))), faces, typeof(np.zeros(3)))}


# The winding kernels a helper process compiles while the command compiles the rest (split_compile.py).
WINDING_KERNELS = (bucket_half_edges, signed_volume)


def warm_up_winding() -> None:
    """The winding's kernels (WINDING_KERNELS): the merged tetrahedron as number_by_first_use gives it (float64
    vertices, int64 faces), closed and consistent (the volume's sign), then with one face turned (the orientation)."""
    vertices = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [2, 1, 3]], np.int64)
    repair_winding(vertices, faces)
    faces[0] = faces[0, ::-1]
    repair_winding(vertices, faces)
