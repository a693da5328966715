"""plane: a grid in the local x–z plane, normal +y; built at its size (a plane has no tube to lose)."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from ..values.fields import KindKeys, Segments, lengths
from .kind import ShapeKind, doublings


def plane_mesh(size, segments) -> tuple[np.ndarray, np.ndarray]:
    """A width × depth grid in the local x–z plane, centred, wound so its normal is +y."""
    nx, nz = segments
    xs = np.linspace(-size[0] / 2, size[0] / 2, nx + 1)
    zs = np.linspace(-size[1] / 2, size[1] / 2, nz + 1)
    x, z = np.meshgrid(xs, zs, indexing="ij")
    vertices = np.column_stack([x.ravel(), np.zeros(x.size), z.ravel()])
    i, k = np.meshgrid(np.arange(nx), np.arange(nz), indexing="ij")
    a = (i * (nz + 1) + k).ravel()
    b, c, d = a + (nz + 1), a + (nz + 1) + 1, a + 1  # (x+1, z), (x+1, z+1), (x, z+1)
    # (a, d, c) and (a, c, b): counter-clockwise seen from +y, so the cross product points up.
    faces = np.concatenate([np.column_stack([a, d, c]), np.column_stack([a, c, b])])
    return vertices, faces


def planar_uv(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3, 2) UVs of a plane in the x–z plane (normal +y): u = 0 → 1 along +x, v = 0 → 1 along −z (the
    image upright when seen from above with −z away), over the plane's extent."""
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    span = np.where(high > low, high - low, 1.0)
    corners = vertices[faces]
    return np.stack([(corners[..., 0] - low[0]) / span[0], (high[2] - corners[..., 2]) / span[2]], axis=-1)


class PlaneKeys(KindKeys):
    """A flat grid in its local x–z plane, normal +y, one-sided as every face is."""
    size: lengths(2, "[width, depth]") | None = Field(None, description=(
        "[width, depth] in its local x–z plane (normal +y), default [2, 2]"))
    segments: Segments | None = Field(None, description="[x, z] cells, default [1, 1]")


class Plane(ShapeKind):
    name = "plane"
    keys = PlaneKeys
    curved = False

    def template(self, obj):
        return plane_mesh(obj.size or (2.0, 2.0), obj.segments or (1, 1))

    def triangles(self, obj):
        nx, nz = obj.segments or (1, 1)
        return 2 * nx * nz

    def uv(self, obj, vertices, faces):
        return planar_uv(vertices, faces)

    def refined(self, obj, level):
        return {"segments": [2 ** level, 2 ** level]}

    def level_of(self, obj):
        return doublings((obj.segments or (1, 1))[0], 1)
