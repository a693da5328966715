"""Repair what a mesh file gets wrong for shading: points it repeats (merged) and faces wound inconsistently
(made consistent, and outward when the mesh is closed). Vectorised numpy on the raw arrays, linear or
n log n in the triangles (docs/performance.md, "Mesh files at millions of triangles").
"""

from __future__ import annotations

import numpy as np

from ..records import bounding_box
from .normals import FACE_CHUNK, cross_rows


def repair_winding(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, int, bool]:
    """Make a mesh file's winding consistent, and outward if the mesh is closed.

    Inconsistent winding makes face normals of neighbours cancel in the vertex-normal mean. Returns
    the faces, how many were flipped, and whether the mesh is closed (every edge in exactly two faces:
    then it is turned outward, by its signed volume). A consistent mesh, the common case, costs one
    sort of its 3F half-edges (and a closed one its signed volume, taken over the whole mesh as trimesh's
    fix_inversion did: a consistent mesh whose pieces disagree is left to its majority by volume); only an
    inconsistent one pays for the face graph (`_orient_faces`), which also orients each piece by its own volume.
    """
    keys = _half_edge_keys(faces, len(vertices))
    keys.sort()
    # Closed: the sorted undirected edges come in pairs, each pair unlike its neighbours.
    closed = (len(keys) % 2 == 0 and bool(((keys[0::2] >> 1) == (keys[1::2] >> 1)).all())
              and not ((keys[1:-1:2] >> 1) == (keys[2::2] >> 1)).any())
    # Consistent: no half-edge is traversed twice in the same direction (by two faces or a duplicate face).
    if not (keys[1:] == keys[:-1]).any():
        del keys
        if closed and _signed_volumes(vertices, faces)[0] < 0:
            return faces[:, ::-1], len(faces), True
        return faces, 0, closed
    del keys
    flip = _orient_faces(vertices, faces, closed)
    repaired = faces.copy()
    repaired[flip] = faces[flip, ::-1]
    return repaired, int(flip.sum()), closed


def _orient_faces(vertices: np.ndarray, faces: np.ndarray, closed: bool) -> np.ndarray:
    """Which faces to flip (F,) bool so that every edge shared by exactly two faces is traversed in
    opposite directions; per connected piece the orientation that flips fewer faces, or, if the mesh is
    closed, the one with positive signed volume. A non-orientable piece (a Möbius strip) is left as it is.

    Orientation is a two-colouring: face f as it is is node f, flipped node f + F; an edge whose two faces
    agree joins (f, g) and (f + F, g + F), one where they disagree (f, g + F) and (f + F, g). The graph's
    connected components (scipy.sparse.csgraph, linear) then give every face's orientation relative to
    its piece at once; a piece whose f and f + F fall in one component cannot be oriented.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    count = len(faces)
    keys = _half_edge_keys(faces, len(vertices))
    order = np.argsort(keys, kind="stable")
    keys, face = keys[order], order // 3
    edge = keys >> 1
    first = np.flatnonzero(np.r_[True, edge[1:] != edge[:-1]])
    runs = np.diff(np.r_[first, len(edge)])
    shared = first[runs == 2]  # manifold edges only: a third face makes orientation ambiguous there
    f, g = face[shared], face[shared + 1]
    agree = (keys[shared] & 1) != (keys[shared + 1] & 1)
    rows = np.concatenate([f, f + count])
    cols = np.concatenate([np.where(agree, g, g + count), np.where(agree, g + count, g)])
    graph = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(2 * count, 2 * count))
    _, label = connected_components(graph, directed=False)
    as_is, flipped = label[:count], label[count:]
    piece = np.minimum(as_is, flipped)  # one name per piece, whichever node carries it
    orientable = as_is != flipped
    # Keep the side of each piece that most faces already have; a closed mesh: the side of positive volume.
    votes = np.bincount(piece, np.where(as_is == piece, 1.0, -1.0), minlength=2 * count)
    flip = orientable & ((as_is == piece) != (votes[piece] >= 0))
    if closed:
        sign = np.where(flip, -1.0, 1.0)
        inward = _signed_volumes(vertices, faces, piece, 2 * count, sign) < 0
        flip ^= orientable & inward[piece]
    return flip


def _half_edge_keys(faces: np.ndarray, vertex_count: int) -> np.ndarray:
    """(3F,) int64, one per half-edge (start → end) of face f's corner k at 3f + k: the undirected edge
    (low · V + high), shifted left one bit for its direction (1 where start > end). Built in place: the
    3F half-edges are the largest arrays of mesh preparation."""
    start = np.ascontiguousarray(faces, np.int64).ravel()
    end = np.roll(faces, -1, axis=1).astype(np.int64).ravel()
    keys = np.minimum(start, end)
    keys *= vertex_count
    np.maximum(start, end, out=end)
    keys += end
    del end
    keys <<= 1
    keys += np.roll(faces, -1, axis=1).ravel() < start  # start > end
    return keys


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

    What trimesh's process() did that matters for shading: a file that repeats a point for every face
    around it (STL always, OBJ and PLY often) must share it, or the vertex-normal mean sees one face
    and the surface shades faceted. As process(), vertices whose file normals (V, 3) differ (rounded to
    0.01) stay apart: a hard edge the file draws stays hard. Unlike process(): positions are compared
    exactly (−0 = +0), not rounded to trimesh's 1e-8 grid, and UV coordinates do not keep two vertices
    apart (the renderer reads no textures: a texture seam is no edge of the surface). Rows are hashed
    to one uint64 and the hashes sorted (V log V, numpy's vectorised sort); equal hashes are then
    checked value by value.
    """
    used = np.zeros(len(vertices), bool)
    used[faces] = True
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
            return vertices, faces  # nothing to merge or drop: no copies
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
