"""Face and vertex normals of a triangle mesh: unit face normals, the vertex normal at every face corner
(mean, area- or angle-weighted, split at creases), a file's normals gathered to the corners.

Vertex normals are stored per face corner, so a crease split or normals read from a file need no
vertex duplication: corner (f, k) carries the normal that vertex faces[f, k] has *on face f*.
"""

from __future__ import annotations

import math

import numpy as np

from ..tolerances import NO_DIRECTION
from .kernels import face_normals_into, gather_corners, normalise_sums, vertex_normal_sums

FACE_CHUNK = 1 << 18  # faces per step of a per-face computation: ~25 MB of temporaries, whatever the mesh


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals (F, 3) (zero for a degenerate face) and twice the areas (F,): one compiled pass
    over the faces (kernels.face_normals_into), no per-face temporaries."""
    unit, doubled_area = np.zeros((len(faces), 3)), np.empty(len(faces))
    face_normals_into(vertices, faces, unit, doubled_area)
    return unit, doubled_area


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b row by row, (N, 3): np.cross's arithmetic (so its bits) without its (N, 3) temporaries."""
    cross = np.empty_like(a)
    for k in range(3):
        i, j = (k + 1) % 3, (k + 2) % 3
        np.subtract(a[:, i] * b[:, j], a[:, j] * b[:, i], out=cross[:, k])
    return cross


def corner_angles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Interior angle at each corner (F, 3), radians; 0 at a degenerate corner."""
    corners = vertices[faces]
    angles = np.zeros(faces.shape)
    for k in range(3):
        a = corners[:, (k + 1) % 3] - corners[:, k]
        b = corners[:, (k + 2) % 3] - corners[:, k]
        # atan2(|a×b|, a·b) is accurate at every angle, unlike acos of a normalised dot.
        angles[:, k] = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))
    return angles


def corner_weights(vertices: np.ndarray, faces: np.ndarray, doubled_area: np.ndarray, weighting: str):
    """The weight w of each face corner in a vertex normal's sum Σ w n_f: None for "mean" (w = 1), the face's
    doubled area (F, 3) for "area", the corner angle (F, 3) for "angle"."""
    if weighting == "mean":
        return None
    if weighting == "area":
        return np.repeat(doubled_area[:, None], 3, axis=1)
    if weighting == "angle":
        return corner_angles(vertices, faces)
    raise ValueError(f"unknown normal weighting {weighting!r}")


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
    # Σ w n_f and Σ w |n_f| (the length the sum would have if every normal agreed) per vertex, added in the
    # corners' order (the order of the additions fixes the last bits): one pass, no per-corner arrays.
    summed = vertex_normal_sums(faces, unit, np.empty((0, 3)) if weights is None else weights, weights is not None,
                                len(vertices))
    vertex_normal, vague = normalise_sums(summed, NO_DIRECTION)  # no direction: the face normal (as _normalise_or)
    del summed
    corner_vertex = faces.ravel()
    split = _creased_vertices(unit, corner_vertex, vertex_normal, vague, crease_angle)
    corners = _corners_of(vertex_normal, vague, faces, unit, dtype)
    if split.any():
        # Corners at a vertex with a crease: each gathers only the faces within the angle of its own.
        length = np.linalg.norm(unit, axis=1)
        reach = (np.repeat(length, 3) if weights is None else (weights * length[:, None]).ravel())
        picked = np.flatnonzero(split[corner_vertex])
        face = picked // 3
        contribution = np.column_stack([_corner_terms(unit, weights, i)[picked] for i in range(3)] + [reach[picked]])
        sums = _creased_sums(corner_vertex[picked], contribution, unit[face], crease_angle)
        corners.reshape(-1, 3)[picked] = _normalise_or(sums[:, :3], unit[face], sums[:, 3:])
    return corners


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


def file_corner_normals(file_normals: np.ndarray, faces: np.ndarray, unit: np.ndarray,
                        dtype: type = np.float64) -> np.ndarray:
    """Corner normals (F, 3, 3) from a file's vertex normals (V, 3), placed (geometry.place): each unit
    length, and a vertex normal without direction (≤ NO_DIRECTION, as _normalise_or) gives way to the face
    normal `unit` (F, 3). Normalised per vertex, then gathered: no (F, 3, 3) float64 temporaries."""
    length = np.linalg.norm(file_normals, axis=1, keepdims=True)
    vague = (length <= NO_DIRECTION).ravel()
    return _corners_of(file_normals / np.where(vague[:, None], 1.0, length), vague, faces, unit, dtype)


def _corners_of(vertex_normal: np.ndarray, vague: np.ndarray, faces: np.ndarray, unit: np.ndarray,
                dtype: type) -> np.ndarray:
    """(F, 3, 3) in `dtype`: each corner its vertex's normal (V, 3), or its face's `unit` normal where the
    vertex is `vague` (V,) bool (its normal has no direction)."""
    corners = np.empty((len(faces), 3, 3), dtype)
    gather_corners(vertex_normal, vague, faces, unit, corners)
    return corners


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


def _normalise_or(vectors: np.ndarray, fallback: np.ndarray, reach: np.ndarray | float = 1.0) -> np.ndarray:
    """Unit vectors; the fallback where a vector has no direction: a length at most NO_DIRECTION × `reach`,
    the length it would have if its parts agreed (a sum of unit normals that nearly cancels points
    wherever rounding sends it). The shading kernel applies the same tolerance to its mixed normals."""
    length = np.linalg.norm(vectors, axis=-1, keepdims=True)
    tiny = length <= NO_DIRECTION * np.asarray(reach)
    return np.where(tiny, fallback, vectors / np.where(tiny, 1.0, length))
