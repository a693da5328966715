"""icosphere: the regular icosahedron subdivided, every new vertex pushed out to the unit sphere."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from pydantic import Field

from ..values.fields import KindKeys, Length, Whole
from .kind import ShapeKind
from .surfaces import sphere_uv


@lru_cache(maxsize=1)
def icosahedron() -> tuple[np.ndarray, np.ndarray]:
    """The regular icosahedron on the unit sphere: vertices the cyclic permutations of (±1, ±φ, 0), faces the
    20 triples of mutually adjacent vertices (edge length 2 before normalising), wound outward. Built once
    (a scene may hold thousands of icospheres); the arrays are read-only."""
    phi = (1.0 + 5.0 ** 0.5) / 2.0
    signs = np.array([[-1, 1], [1, 1], [-1, -1], [1, -1]], np.float64)
    seed = np.column_stack([signs[:, 0], signs[:, 1] * phi, np.zeros(4)])        # (±1, ±φ, 0)
    vertices = np.concatenate([np.roll(seed, shift, axis=1) for shift in range(3)])
    # Neighbours are 2 apart; the next distance is 2φ ≈ 3.24, so 2.5 separates them whatever the rounding.
    gap = np.linalg.norm(vertices[:, None] - vertices[None], axis=2)
    near = (gap > 0) & (gap < 2.5)
    i, j, k = np.nonzero(near[:, :, None] & near[:, None, :] & near[None, :, :])
    faces = np.column_stack([i, j, k])[(i < j) & (j < k)]
    # Outward: for a convex solid around the origin, det[a, b, c] > 0 is a counter-clockwise face seen from outside.
    inward = np.linalg.det(vertices[faces]) < 0
    faces[inward] = faces[inward][:, [0, 2, 1]]
    vertices = vertices / np.linalg.norm(vertices, axis=1, keepdims=True)
    vertices.flags.writeable = faces.flags.writeable = False
    return vertices, faces


def icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere: the icosahedron with every triangle split in four `subdivisions` times, each new
    edge midpoint pushed out to the sphere; 20·4^subdivisions faces."""
    vertices, faces = (array.copy() for array in icosahedron())
    for _ in range(subdivisions):
        # One midpoint per undirected edge: edge k of a face runs from corner k to corner k + 1.
        start, end = faces.ravel(), faces[:, [1, 2, 0]].ravel()
        low, high = np.minimum(start, end), np.maximum(start, end)
        edges, midpoint = np.unique(low * len(vertices) + high, return_inverse=True)
        low, high = np.divmod(edges, len(vertices))
        middle = (vertices[low] + vertices[high]) * 0.5
        middle /= np.linalg.norm(middle, axis=1, keepdims=True)
        m = midpoint.reshape(-1, 3) + len(vertices)  # m[:, k]: midpoint of edge k
        a, b, c = faces.T
        # Three corner triangles and the middle one, each wound as its parent.
        faces = np.concatenate([np.column_stack(corner) for corner in
                                ((a, m[:, 0], m[:, 2]), (m[:, 0], b, m[:, 1]), (m[:, 2], m[:, 1], c), m.T)])
        vertices = np.concatenate([vertices, middle])
    return vertices, faces


MAX_SUBDIVISIONS = 8  # 20·4^8 = 1.3 M triangles an object: finer is a mesh file's job


class IcosphereKeys(KindKeys):
    """A sphere from an icosahedron whose faces are subdivided and pushed onto the sphere."""
    radius: Length = Field(1.0, description="the radius")
    subdivisions: Whole = Field(2, ge=0, le=MAX_SUBDIVISIONS, description=(
        "each subdivision splits every face of the icosahedron into four: 20·4^n faces"))


class Icosphere(ShapeKind):
    name = "icosphere"
    keys = IcosphereKeys
    size_key = "subdivisions"
    max_level = MAX_SUBDIVISIONS

    def lengths(self, obj):
        return (obj.radius,)

    def unit_mesh(self, obj, unit):
        return icosphere(obj.subdivisions)

    def triangles(self, obj):
        return 20 * 4 ** obj.subdivisions

    def uv(self, obj, vertices, faces):
        return sphere_uv(vertices, faces)

    def exact_normals(self, obj, corners, flat):
        return corners  # p / |p|

    def refined(self, obj, level):
        return {"subdivisions": level}  # 20·4^L triangles

    def level_of(self, obj):
        return obj.subdivisions

    def finer(self, obj, more):
        return f"subdivisions = {obj.subdivisions + more}"
