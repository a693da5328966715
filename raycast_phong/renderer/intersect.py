"""Build the BVH once, answer closest-hit and occlusion queries in float32: Embree's C API (embree_library.py)
through numba kernels on packets of 16 rays, the renderer's one engine.

Embree works in float32, so the scene is moved and scaled to unit size in float64 first (Frame):
a model far from the origin keeps its low-order bits. A miss has face −1, u = v = 0 and t = 1e37
(embreex's "no limit"), and NaN vertices or rays silently miss (the scene loader refuses non-finite
input before it gets here).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..records import Frame, Geometry, bounding_box
from . import embree_library
from .kernels import ray_queries

_started = False  # has this process created an Embree scene (and so Embree's worker threads)?


def embree_started() -> bool:
    """Whether this process has started Embree: after that, forking it is unsafe (its thread pool's
    locks would be copied in whatever state they are in)."""
    return _started


def unit_frame(vertices: np.ndarray) -> Frame:
    """Centre and half-extent of the bounding box: unit = (world − center) / scale spans ≈ [−1, 1]."""
    return frame_of_box(*bounding_box(vertices))


def frame_of_box(low: np.ndarray, high: np.ndarray) -> Frame:
    """unit_frame of vertices whose bounding box is (low, high) (a Geometry's: Geometry.box, measured once)."""
    extent = float((high - low).max()) / 2
    # A single point or a degenerate scene still needs a non-zero scale.
    return Frame(center=(low + high) / 2, scale=extent if extent > 0 else 1.0)


@dataclass(frozen=True, eq=False)
class TileHits:
    """Closest hit of each ray of a tile, aligned index for index with its rays."""
    face: np.ndarray  # (N,) int32, -1 where the ray missed
    u: np.ndarray     # (N,) float32, barycentric weight of corner 1
    v: np.ndarray     # (N,) float32, barycentric weight of corner 2
    t: np.ndarray     # (N,) float32, distance in the unit frame (× Frame.scale for world units)


class Accelerator:
    """Embree BVH over one Geometry, built (committed) in the constructor so threads may share it.

    `embree_scene.scene` is the C API's scene: kernels query it directly (ray_queries.py's rtc_intersect16 /
    rtc_occluded16) while this object lives. EmbreeError if Embree's library cannot be loaded.
    """

    def __init__(self, geometry: Geometry, frame: Frame | None = None):
        self._commit(geometry.vertices, geometry.faces, frame)

    @classmethod
    def of_mesh(cls, vertices: np.ndarray, faces: np.ndarray, frame: Frame | None = None) -> Accelerator:
        """The BVH of a Geometry's vertices (V, 3) and faces (F, 3) given apart (before its normals exist)."""
        accelerator = cls.__new__(cls)
        accelerator._commit(vertices, faces, frame)
        return accelerator

    def _commit(self, vertices: np.ndarray, faces: np.ndarray, frame: Frame | None) -> None:
        global _started
        _started = True
        self.frame = frame or unit_frame(vertices)
        self.embree_scene = embree_library.EmbreeScene(embree_library.library(), self.frame.to_unit(vertices), faces)

    def closest_hits(self, origins: np.ndarray, directions: np.ndarray, row_rays: int = 4) -> TileHits:
        """Closest hit along each ray; origins and unit directions (N, 3) float32 in the unit frame.
        row_rays: the rays form an image of rows this long (4 × 4 neighbours share an Embree packet)."""
        count = len(origins)
        hits = TileHits(face=np.empty(count, np.int32), u=np.empty(count, np.float32),
                        v=np.empty(count, np.float32), t=np.empty(count, np.float32))
        ray_queries.intersect_rays(self.embree_scene.scene, _f32(origins), _f32(directions), row_rays,
                              hits.face, hits.u, hits.v, hits.t)
        return hits

    def cast_packets(self, packets: np.ndarray, valid: np.ndarray) -> None:
        """rtcIntersect16 on prepared packets (packed_rays), hits left in them: Embree's own cost of the rays."""
        ray_queries.cast_packets(self.embree_scene.scene, packets, valid)

    def occluded(self, origins: np.ndarray, directions: np.ndarray, t_max: np.ndarray) -> np.ndarray:
        """(N,) bool: something lies on the ray within (0, t_max], t_max (N,) float32."""
        blocked = np.empty(len(origins), np.bool_)
        ray_queries.occluded_rays(self.embree_scene.scene, _f32(origins), _f32(directions), _f32(t_max, 1), blocked)
        return blocked


def packed_rays(origins: np.ndarray, directions: np.ndarray, row_rays: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Rays (N, 3) as Embree's RTCRayHit16 packets (P, PACKET_WORDS) float32 and valid masks (P, 16) int32,
    64-byte aligned, in closest_hits' 4 × 4 blocks of an image of rows row_rays long (for cast_packets)."""
    rows = -(-len(origins) // row_rays)
    blocks = -(-rows // 4) * -(-row_rays // 4)
    packets = _aligned((blocks, ray_queries.PACKET_WORDS), np.float32)
    valid = _aligned((blocks, 16), np.int32)
    ray_queries.fill_packets(_f32(origins), _f32(directions), row_rays, packets, valid)
    return packets, valid


def _aligned(shape: tuple[int, int], dtype: type) -> np.ndarray:
    """A zeroed C-contiguous array whose data starts on a 64-byte boundary (Embree's 16-lane loads)."""
    size = shape[0] * shape[1] * np.dtype(dtype).itemsize
    store = np.zeros(size + 64, np.uint8)
    start = -store.ctypes.data % 64
    return store[start:start + size].view(dtype).reshape(shape)


def _f32(array: np.ndarray, ndim: int = 2) -> np.ndarray:
    """The kernels' layout: C-contiguous float32 (a no-op for the tiles' own arrays)."""
    return np.ascontiguousarray(array, np.float32).reshape((-1, 3) if ndim == 2 else -1)
