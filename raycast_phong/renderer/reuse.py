"""What the frames of one changing scene reuse (a live view keeps one FrameCache per page): the geometry and its
groups' pieces (geometry.memo.BuildMemo), the committed BVH, and what is computed from the geometry's arrays
alone (Derived). Whatever is reused is what a frame without the cache would compute, bit for bit: every piece
is keyed by what it was made from, and arrays are compared by their bits.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from ..geometry.memo import BuildMemo
from ..records import Frame, Geometry
from .intersect import Accelerator


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two arrays hold the same bits (not only equal values: -0.0 is not 0.0 here)."""
    if a is b:
        return True
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    return bool(np.array_equal(np.ascontiguousarray(a).view(np.uint8), np.ascontiguousarray(b).view(np.uint8)))


class Derived:
    """Values computed from one Geometry's arrays alone (its unit frame, diagnose's per-object figures, the
    kernels' geometry tables), each with the names of the Geometry fields it was computed from. A new Geometry
    takes over the values whose fields hold the same bits in both (a shading switch keeps the vertices, so
    their frame and per-object bounds, and rebuilds what the new corner normals change)."""

    def __init__(self, geometry: Geometry, before: Derived | None = None):
        self.geometry = geometry
        self._values: dict[Any, tuple[tuple[str, ...], Any]] = {}
        if before is not None:
            @functools.cache  # each field compared once, however many values name it
            def unchanged(name: str) -> bool:
                old, new = getattr(before.geometry, name), getattr(geometry, name)
                return old is new or (isinstance(old, np.ndarray) and isinstance(new, np.ndarray)
                                      and same_bits(old, new))
            self._values = {key: (fields, value) for key, (fields, value) in before._values.items()
                            if all(unchanged(name) for name in fields)}

    def get(self, key: Any, fields: tuple[str, ...], make: Callable[[], Any]) -> Any:
        """make(), computed from the Geometry `fields` only, or the value it gave before for the same bits."""
        found = self._values.get(key)
        if found is None:
            found = self._values[key] = (fields, make())
        return found[1]


class FrameCache:
    """What the frames of one changing scene share (a live view keeps one per page, and drops it with the page):
    build_geometry's memo (the last Geometry and its groups' pieces, each keyed by what it was built from), the
    committed BVH of the last frame with the vertices and faces it was built on, and the values Derived from the
    last Geometry. A frame whose arrays hold the same bits (a new light, camera, material, shading or precision)
    reuses the BVH; any other builds a new one, the old one dropped first so that two BVHs of a large mesh never
    live at once. The lock lets two threads share one cache safely, one at a time.
    """

    def __init__(self):
        self.lock = threading.Lock()
        self.memo = BuildMemo()
        self._bvh: tuple[np.ndarray, np.ndarray, Accelerator] | None = None
        self._derived: Derived | None = None

    def accelerator(self, geometry: Geometry, frame: Frame) -> Accelerator:
        """The committed BVH of `geometry`: the last one if it was built on the same vertices and faces."""
        with self.lock:
            if self._bvh is not None:
                vertices, faces, accelerator = self._bvh
                if same_bits(vertices, geometry.vertices) and same_bits(faces, geometry.faces):
                    return accelerator
            self._bvh = None
            accelerator = Accelerator(geometry, frame)
            self._bvh = (geometry.vertices, geometry.faces, accelerator)
            return accelerator

    def derived(self, geometry: Geometry) -> Derived:
        """The Derived values of `geometry`, with what it shares with the last Geometry taken over."""
        with self.lock:
            if self._derived is None or self._derived.geometry is not geometry:
                self._derived = Derived(geometry, self._derived)
            return self._derived

    @property
    def geometry(self) -> Geometry | None:
        """The Geometry of the newest frame that derived values from it (None before the first frame)."""
        with self.lock:
            return None if self._derived is None else self._derived.geometry

    def clear(self) -> None:
        """Release the geometry, its pieces, the BVH and the derived values."""
        with self.lock:
            self.memo, self._bvh, self._derived = BuildMemo(), None, None
