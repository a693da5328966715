"""Face and vertex normals of a triangle mesh: unit face normals, the vertex normal at every face corner
(mean, area- or angle-weighted, split at creases), a file's normals gathered to the corners.

Vertex normals are stored per face corner, so a crease split or normals read from a file need no
vertex duplication: corner (f, k) carries the normal that vertex faces[f, k] has *on face f*.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from contextvars import ContextVar
from itertools import pairwise

import numpy as np

from ..io.system import default_threads
from ..tolerances import NO_DIRECTION
from .kernels import (
    creased_corners,
    face_normals_into,
    gather_corners,
    gather_corners_creased,
    normalise_sums,
    vertex_normal_sums,
)

FACE_CHUNK = 1 << 18  # faces per step of a per-face computation: ~25 MB of temporaries, whatever the mesh

# A mesh of at least this many faces runs the passes that split bit for bit on the preparation's threads; a smaller
# one (every built-in scene's start-up) on the calling thread alone. At 200k faces a pass takes 5-20 ms, starting
# a thread 0.1 ms.
PARALLEL_FACES = 200_000
_THREADS: ContextVar[int | None] = ContextVar("prep_threads", default=None)


@contextmanager
def prep_threads(threads: int | None) -> Iterator[None]:
    """The preparation's threads for the calls inside (the render's `threads`, as its tiles get; None: the
    machine's cores, at most 8, as the render's default). A batch's worker renders with one thread: no more."""
    token = _THREADS.set(threads)
    try:
        yield
    finally:
        _THREADS.reset(token)


def parts(count: int, faces: int, running: Callable[[], np.ndarray] | None = None) -> list[tuple[int, int]]:
    """[0, count) cut into one range [low, high) per preparation thread when the mesh has at least PARALLEL_FACES
    `faces` (else the whole range: no thread is started). `running`: gives the work done up to each item (count + 1,),
    non-decreasing (called only when the range is cut), to cut at equal shares of it instead of equal lengths."""
    threads = _THREADS.get() or default_threads()
    if faces < PARALLEL_FACES or threads < 2 or count < threads:
        return [(0, count)]
    if running is None:
        cuts = [count * i // threads for i in range(threads + 1)]
    else:
        total = running()
        cuts = [0, *np.searchsorted(total, total[-1] * np.arange(1, threads) / threads).tolist(), count]
    return [(low, high) for low, high in pairwise(cuts) if high > low]


def run_parts(step: Callable[[int, int], object], ranges: list[tuple[int, int]]) -> list:
    """step(low, high) for each range, the first on this thread and each other on a thread of its own (the
    kernels release the GIL), joined before returning; their results in order."""
    if len(ranges) == 1:
        return [step(*ranges[0])]
    with ThreadPoolExecutor(max_workers=len(ranges) - 1) as pool:
        others = [pool.submit(step, *part) for part in ranges[1:]]
        return [step(*ranges[0]), *(future.result() for future in others)]


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals (F, 3) (zero for a degenerate face) and twice the areas (F,): one compiled pass
    over the faces (kernels.face_normals_into), no per-face temporaries; above PARALLEL_FACES, one slice of
    the faces per thread."""
    unit, doubled_area = np.zeros((len(faces), 3)), np.empty(len(faces))
    run_parts(lambda low, high: face_normals_into(vertices, faces[low:high], unit[low:high], doubled_area[low:high]),
              parts(len(faces), len(faces)))
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
    for the pairwise test (kernels.gather_corners_creased, kernels.creased_corners).
    """
    unit, doubled_area = normals if normals is not None else face_normals(vertices, faces)
    weights = corner_weights(vertices, faces, doubled_area, weighting)
    # Σ w n_f and Σ w |n_f| (the length the sum would have if every normal agreed) per vertex, added in the
    # corners' order (the order of the additions fixes the last bits): one pass, no per-corner arrays; above
    # PARALLEL_FACES each thread sums the vertices of its own range, each still in corner order.
    weighted, weights = weights is not None, np.empty((0, 3)) if weights is None else weights
    count = len(vertices)
    vertex_normal, vague = _vertex_normals(faces, unit, weights, weighted, count)  # vague: take the face normal
    if crease_angle >= 180.0:
        return _corners_of(vertex_normal, vague, faces, unit, dtype)
    # Corners at a vertex with a crease: each gathers only the faces within the angle of its own. A vertex whose
    # face normals all lie within half the angle of its mean normal is not split: any two are then within the
    # angle (triangle inequality on the sphere), so each of its corners gathers every face, the uncreased sum bit
    # for bit. The margin sends a vertex at the bound through the pairwise test instead (the small slack keeps a
    # face and its exact coplanar neighbour together despite rounding). The test runs in the gather's pass.
    half = math.cos(math.radians(crease_angle) / 2) + 1e-9
    corners = np.empty((len(faces), 3, 3), dtype)
    ranges = parts(len(faces), len(faces))
    apart = [np.zeros(count, bool) for _ in ranges]  # one per thread: each sets only its own
    run_parts(lambda low, high: gather_corners_creased(vertex_normal, vague, faces[low:high], unit[low:high], half,
                                                       corners[low:high], apart[ranges.index((low, high))]), ranges)
    split = np.logical_or.reduce([vague, *apart])
    if split.any():  # each range's corners bucketed and summed by its thread: cut by the split vertices
        least = math.cos(math.radians(crease_angle)) - 1e-12
        run_parts(lambda low, high: creased_corners(faces, unit, weights, weighted, split, least, NO_DIRECTION,
                                                    corners, low, high),
                  parts(count, len(faces), lambda: np.r_[0, np.cumsum(split)]))
    return corners


def _vertex_normals(faces: np.ndarray, unit: np.ndarray, weights: np.ndarray, weighted: bool, count: int):
    """The `count` vertex normals (V, 3) and which have no direction (V,) bool, from sums (V, 4) float64 of the
    corners' w n_f and w |n_f| (kernels.vertex_normal_sums, kernels.normalise_sums), freed on return."""
    summed = np.zeros((count, 4))
    run_parts(lambda low, high: vertex_normal_sums(faces, unit, weights, weighted, summed, low, high),
              parts(count, len(faces)))
    vertex_normal, vague = np.empty((count, 3)), np.empty(count, bool)
    run_parts(lambda low, high: normalise_sums(summed[low:high], NO_DIRECTION, vertex_normal[low:high],
                                               vague[low:high]), parts(count, len(faces)))
    return vertex_normal, vague


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
    run_parts(lambda low, high: gather_corners(vertex_normal, vague, faces[low:high], unit[low:high],
                                               corners[low:high]), parts(len(faces), len(faces)))
    return corners


def _normalise_or(vectors: np.ndarray, fallback: np.ndarray, reach: np.ndarray | float = 1.0) -> np.ndarray:
    """Unit vectors; the fallback where a vector has no direction: a length at most NO_DIRECTION × `reach`,
    the length it would have if its parts agreed (a sum of unit normals that nearly cancels points
    wherever rounding sends it). The shading kernel applies the same tolerance to its mixed normals."""
    length = np.linalg.norm(vectors, axis=-1, keepdims=True)
    tiny = length <= NO_DIRECTION * np.asarray(reach)
    return np.where(tiny, fallback, vectors / np.where(tiny, 1.0, length))


# The compiled passes of a crease split: a smooth object with a crease angle below 180°, and a mesh file that
# stores no normals (its crease angle is io.meshes.materials.FILE_CREASE_ANGLE unless the scene sets one).
CREASE_KERNELS = ("gather_corners_creased", "creased_corners")


def warm_up_creases(dtype: type) -> None:
    """Load (or compile) CREASE_KERNELS with the types a render gives them: the corner normals, in `dtype`, of a
    tetrahedron, whose every edge is a crease at 30°."""
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    compute_corner_normals(vertices, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]), "mean", 30.0, dtype)
