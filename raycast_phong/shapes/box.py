"""box: six rectangular sides, two triangles each; its flat faces are exact, so it has one level."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from ..values.fields import KindKeys, lengths
from .kind import ShapeKind

# A box's 12 triangles over its corners 4x + 2y + z (x, y, z ∈ {0, 1}): two per side, counter-clockwise
# seen from outside, split along the same diagonals as trimesh's box.
BOX_FACES = np.array([[1, 3, 0], [0, 3, 2],   # x = 0
                      [4, 1, 0], [5, 1, 4],   # y = 0
                      [2, 4, 0], [6, 4, 2],   # z = 0
                      [1, 7, 3], [5, 7, 1],   # z = 1
                      [3, 7, 2], [2, 7, 6],   # y = 1
                      [6, 5, 4], [7, 5, 6]])  # x = 1


def box(extents) -> tuple[np.ndarray, np.ndarray]:
    """A box of edge lengths `extents` (x, y, z), centred."""
    corners = (np.arange(8)[:, None] >> np.array([2, 1, 0])) & 1
    return (corners - 0.5) * np.asarray(extents, np.float64), BOX_FACES.copy()


def box_uv(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3, 2) UVs of a box: each side shows the whole texture once, projected along its axis (u, v the
    side's two other coordinates over the box's extent, in x, y, z order)."""
    corners = vertices[faces]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    axis = np.abs(normal).argmax(axis=1)
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    span = np.where(high > low, high - low, 1.0)
    scaled = (corners - low) / span
    first = np.array([1, 0, 0])[axis]   # x-side: (y, z); y-side: (x, z); z-side: (x, y)
    second = np.array([2, 2, 1])[axis]
    rows = np.arange(len(faces))[:, None]
    return np.stack([scaled[rows, np.arange(3)[None], first[:, None]],
                     scaled[rows, np.arange(3)[None], second[:, None]]], axis=-1)


class BoxKeys(KindKeys):
    """A box centred on the origin, its sides along the axes."""
    size: lengths(3, "[x, y, z]") | None = Field(None, description="[x, y, z], default [2, 2, 2]")


class Box(ShapeKind):
    name = "box"
    keys = BoxKeys
    size_key = "shape"
    curved = False

    def lengths(self, obj):
        return obj.size or (2.0, 2.0, 2.0)

    def unit_mesh(self, obj, unit):
        return box([length / unit for length in self.lengths(obj)])

    def triangles(self, obj):
        return 12

    def uv(self, obj, vertices, faces):
        return box_uv(vertices, faces)
