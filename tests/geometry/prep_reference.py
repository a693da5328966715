"""The numpy mesh preparation the compiled kernels replaced (geometry/kernels.py, issue 22), kept as the tests'
oracle: the kernels must give its results bit for bit. Helpers both share are imported from the package."""

from __future__ import annotations

import math

import numpy as np

from raycast_phong.geometry.mesh_repair import _merge_sorted, _signed_volumes
from raycast_phong.geometry.normals import FACE_CHUNK, _normalise_or, corner_weights, cross_rows
from raycast_phong.tolerances import NO_DIRECTION


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals (F, 3) (zero for a degenerate face) and twice the areas (F,)."""
    unit, doubled_area = np.zeros((len(faces), 3)), np.empty(len(faces))
    for at in range(0, len(faces), FACE_CHUNK):  # in chunks: the outputs are the only (F, ·) arrays
        part = faces[at:at + FACE_CHUNK]
        first = vertices[part[:, 0]]
        cross = cross_rows(vertices[part[:, 1]] - first, vertices[part[:, 2]] - first)
        area = np.sqrt(cross[:, 0] * cross[:, 0] + cross[:, 1] * cross[:, 1] + cross[:, 2] * cross[:, 2])
        np.divide(cross, area[:, None], out=unit[at:at + FACE_CHUNK], where=area[:, None] > 0)
        doubled_area[at:at + FACE_CHUNK] = area
    return unit, doubled_area



def compute_corner_normals(vertices: np.ndarray, faces: np.ndarray, weighting: str = "mean",
                           crease_angle: float = 180.0, dtype: type = np.float64,
                           normals: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Vertex normal at every face corner (F, 3, 3), unit, in `dtype`.

    n_v = normalize(Σ_f w_f n_f) over the faces f around v, with w = 1 ("mean", the lecture's rule),
    the face area ("area") or the corner angle ("angle"); degenerate faces weigh 0. With a crease
    angle below 180°, corner (f, v) only gathers faces g whose normal is within that angle of n_f.
    A vertex whose sum vanishes falls back to the face normal. `normals`: face_normals(vertices, faces)
    if the caller has them. The sums are per vertex, (V, 4) float64, and only the result is per corner
    (36 bytes a triangle in float32, 72 in float64); only corners at a vertex a crease may split pay
    for the pairwise test (_creased_vertices).
    """
    unit, doubled_area = normals if normals is not None else face_normals(vertices, faces)
    weights = corner_weights(vertices, faces, doubled_area, weighting)
    # w |n_f|: the length the sum would have if every normal agreed (|n_f| is 1, or 0 for a degenerate face).
    length = np.linalg.norm(unit, axis=1)
    reach = (np.repeat(length, 3) if weights is None else (weights * length[:, None]).ravel())
    # Sum per vertex, in the corners' order (the order of the additions fixes the last bits).
    corner_vertex = faces.ravel()
    summed = np.column_stack([np.bincount(corner_vertex, _corner_terms(unit, weights, i), minlength=len(vertices))
                              for i in range(3)] + [np.bincount(corner_vertex, reach, minlength=len(vertices))])
    size = np.linalg.norm(summed[:, :3], axis=1, keepdims=True)
    vague = (size <= NO_DIRECTION * summed[:, 3:]).ravel()  # no direction: the face normal (as _normalise_or)
    vertex_normal = summed[:, :3] / np.where(vague[:, None], 1.0, size)
    del summed, size
    split = _creased_vertices(unit, corner_vertex, vertex_normal, vague, crease_angle)
    corners = _corners_of(vertex_normal, vague, faces, unit, dtype)
    if split.any():
        # Corners at a vertex with a crease: each gathers only the faces within the angle of its own.
        picked = np.flatnonzero(split[corner_vertex])
        face = picked // 3
        contribution = np.column_stack([_corner_terms(unit, weights, i)[picked] for i in range(3)] + [reach[picked]])
        sums = _creased_sums(corner_vertex[picked], contribution, unit[face], crease_angle)
        corners.reshape(-1, 3)[picked] = _normalise_or(sums[:, :3], unit[face], sums[:, 3:])
    return corners



def _corners_of(vertex_normal: np.ndarray, vague: np.ndarray, faces: np.ndarray, unit: np.ndarray,
                dtype: type) -> np.ndarray:
    """(F, 3, 3) in `dtype`: each corner its vertex's normal (V, 3), or its face's `unit` normal where the
    vertex is `vague` (V,) bool (its normal has no direction)."""
    corners = vertex_normal.astype(dtype, copy=False)[faces]
    face, corner = np.nonzero(vague[faces])
    corners[face, corner] = unit[face]
    return corners



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



def merge_duplicate_vertices(vertices: np.ndarray, faces: np.ndarray,
                             normals: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """merge_duplicate_vertices as it was before the hash table: the package\'s sort-based path
    (mesh_repair._merge_sorted, row hashes sorted, then compared value by value) on every row."""
    used = np.zeros(len(vertices), bool)
    used[faces] = True
    return _merge_sorted(vertices, faces, normals, used)


def _creased_vertices(unit, corner_vertex, vertex_normal, vague, crease_angle) -> np.ndarray:
    """(V,) bool: vertices whose faces do not all lie within `crease_angle` of each other, so a crease
    may split them. A vertex whose face normals all lie within half the angle of its mean normal is
    not: any two are then within the angle (triangle inequality on the sphere), and every corner there
    gathers every face, which is the uncreased sum, bit for bit (the same additions in the same order).
    Only the others pay for the (corner, neighbour) pairs of _creased_sums."""
    if crease_angle >= 180.0:
        return np.zeros(len(vertex_normal), bool)
    cosine = np.zeros(len(corner_vertex))
    for i in range(3):
        cosine += np.repeat(unit[:, i], 3) * vertex_normal[corner_vertex, i]
    least = np.full(len(vertex_normal), np.inf)
    np.minimum.at(least, corner_vertex, cosine)
    # The margin sends a vertex at the bound through the exact pairwise test instead.
    return vague | ~(least >= math.cos(math.radians(crease_angle) / 2) + 1e-9)


def _corner_terms(unit: np.ndarray, weights: np.ndarray | None, axis: int) -> np.ndarray:
    """(3F,) w n_f[axis] for every corner, in corner order; weights (F, 3), or None for all ones."""
    if weights is None:
        return np.repeat(unit[:, axis], 3)
    return (weights * unit[:, axis, None]).ravel()


PAIR_CHUNK = 1 << 20  # (corner, neighbour) pairs per step of _creased_sums: ~60 MB of temporaries


def _creased_sums(corner_vertex, contribution, corner_face_normal, crease_angle):
    """For each corner, the sum of contributions of the corners at the same vertex whose faces are
    within `crease_angle` of its own face. corner_face_normal (C, 3) is indexed like the corners.

    A vertex of valence s makes s² (corner, neighbour) pairs, so they are made PAIR_CHUNK at a time
    (whole corners per step: each corner's sum is added in the same order whatever the chunking).
    """
    order = np.argsort(corner_vertex, kind="stable")
    sorted_vertex = corner_vertex[order]
    start = np.searchsorted(sorted_vertex, sorted_vertex, side="left")
    count = np.searchsorted(sorted_vertex, sorted_vertex, side="right") - start
    del sorted_vertex
    # The small slack keeps a face and its exact coplanar neighbour together despite rounding.
    least = math.cos(math.radians(crease_angle)) - 1e-12
    sums = np.zeros((len(order), contribution.shape[1]))
    pairs_before = np.cumsum(count) - count
    cuts = np.searchsorted(pairs_before, np.arange(0, pairs_before[-1] + count[-1], PAIR_CHUNK)) if len(order) else []
    for first, last in zip(cuts, [*cuts[1:], len(order)]):
        if first == last:
            continue
        # Every (corner, neighbour corner) pair that shares a vertex, in sorted positions.
        here = count[first:last]
        mine = np.repeat(np.arange(first, last), here)
        neighbour = start[mine] + (np.arange(len(mine)) - np.repeat(pairs_before[first:last] - pairs_before[first],
                                                                    here))
        neighbour = order[neighbour]
        cosine = np.einsum("ij,ij->i", corner_face_normal[order[mine]], corner_face_normal[neighbour])
        smooth = cosine >= least
        mine, neighbour = mine[smooth] - first, neighbour[smooth]  # mine: row within this chunk
        rows = order[first:last]
        for i in range(contribution.shape[1]):
            sums[rows, i] = np.bincount(mine, contribution[neighbour, i], minlength=last - first)
    return sums
