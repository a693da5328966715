"""The built-in shapes as (vertices (V, 3) float64, faces (F, 3) int64), closed and wound outward, in numpy.

The triangles are those trimesh.creation builds (same positions to float64 rounding, same faces and
orientation, another order), so images rendered before keep their references; trimesh itself is imported
only for mesh files. Nothing is cleaned afterwards: a point on the axis of revolution is one vertex by
construction, and only the triangles that would join it to itself are left out. trimesh instead merges
vertices closer than an absolute 1e-8 and drops revolved triangles of area below 1e-8, which opens holes
near the poles of a fine uv sphere (4096 × 96 segments). Every shape is centred on the origin; revolved
shapes turn about z.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

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


def revolve(radius: np.ndarray, height: np.ndarray, sections: int, closed: bool = False
            ) -> tuple[np.ndarray, np.ndarray]:
    """The surface swept by the profile (radius[k], height[k]) turning about z in `sections` equal steps.

    Profile segment k → k+1 (and the last → the first if `closed`) gives two triangles per step, wound
    outward when the profile runs counter-clockwise in the (radius, height) half-plane. A profile point with
    radius exactly 0 lies on the axis: it is one vertex, and the triangle that would join it to itself is left out.
    """
    on_axis = radius == 0
    theta = np.linspace(0.0, 2.0 * np.pi, sections + 1)[:-1]
    ring = ~on_axis
    # Vertices: the off-axis points step by step (step-major), then each axis point once.
    around = np.stack([np.cos(theta)[:, None] * radius[ring], np.sin(theta)[:, None] * radius[ring],
                       np.broadcast_to(height[ring], (sections, ring.sum()))], axis=2).reshape(-1, 3)
    axis = np.column_stack([np.zeros((on_axis.sum(), 2)), height[on_axis]])
    # index[j, k]: the vertex of profile point k at step j.
    index = np.empty((sections, len(radius)), np.int64)
    index[:, ring] = np.arange(len(around)).reshape(sections, -1)
    index[:, on_axis] = len(around) + np.arange(on_axis.sum())
    k = np.arange(len(radius) if closed else len(radius) - 1)
    k1 = (k + 1) % len(radius)
    here, there = index, np.roll(index, -1, axis=0)  # step j and step j + 1 (the last wraps to the first)
    first = np.stack([here[:, k], there[:, k], here[:, k1]], axis=2)[:, ~on_axis[k]]
    second = np.stack([here[:, k1], there[:, k], there[:, k1]], axis=2)[:, ~on_axis[k1]]
    return np.concatenate([around, axis]), np.concatenate([first.reshape(-1, 3), second.reshape(-1, 3)])


def uv_sphere(segments) -> tuple[np.ndarray, np.ndarray]:
    """Unit UV sphere as trimesh counts it: segments (a, b) give a (rounded up to even) latitude points from
    pole to pole and 2b (b rounded up to even) longitude steps."""
    latitude, longitude = (s + s % 2 for s in segments)
    theta = np.linspace(0.0, np.pi, latitude)
    radius = np.sin(theta)
    radius[[0, -1]] = 0.0  # the poles (sin π is 1.2e-16, not 0)
    return revolve(radius, -np.cos(theta), 2 * longitude)


def cylinder(radius: float, height: float, sections: int) -> tuple[np.ndarray, np.ndarray]:
    """A capped cylinder about z of the given radius and height, centred; `sections` steps around."""
    half = height / 2.0
    return revolve(np.array([0.0, radius, radius, 0.0]), np.array([-half, -half, half, half]), sections)


def torus(major_radius: float, minor_radius: float, major_sections: int, minor_sections: int
          ) -> tuple[np.ndarray, np.ndarray]:
    """A torus about z: a tube of radius minor_radius whose centre circle has radius major_radius."""
    phi = np.linspace(0.0, 2.0 * np.pi, minor_sections + 1)[:-1]
    return revolve(minor_radius * np.cos(phi) + major_radius, minor_radius * np.sin(phi), major_sections,
                   closed=True)


# ---------------------------------------------------------------- texture coordinates per face corner

def _seamless(u: np.ndarray) -> np.ndarray:
    """Corner longitudes (F, 3) in [0, 1) made continuous across the seam: a face whose corners span more
    than half a turn has its small ones moved up by 1 (so u runs 0.97 → 1.02, not 0.97 → 0.02). NaN (a
    pole corner, no longitude) stays NaN."""
    u = u.copy()
    wide = np.fmax.reduce(u, axis=1) - np.fmin.reduce(u, axis=1) > 0.5  # NaN (a pole corner) ignored
    u[wide] = np.where(u[wide] < 0.5, u[wide] + 1.0, u[wide])
    return u


def sphere_uv(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3, 2) UVs of a sphere about z: u = longitude / 2π (atan2(y, x), in [0, 1)), v = (latitude + π/2) / π
    (0 at the −z pole, 1 at +z). A pole corner (no longitude) takes the mean u of its face's other corners."""
    corners = vertices[faces]
    r = np.linalg.norm(corners, axis=-1)
    u = (np.arctan2(corners[..., 1], corners[..., 0]) / (2 * np.pi)) % 1.0
    v = 0.5 + np.arcsin(np.clip(corners[..., 2] / np.where(r > 0, r, 1), -1, 1)) / np.pi
    pole = np.hypot(corners[..., 0], corners[..., 1]) <= 1e-12 * np.maximum(r, 1e-300)
    u = _seamless(np.where(pole, np.nan, u))
    others = np.where(pole, np.nan, u)
    mean = np.nanmean(np.where(np.isnan(others), np.nan, others), axis=1, keepdims=True)
    u = np.where(pole, np.broadcast_to(mean, u.shape), u)
    return np.stack([u, v], axis=-1)


def planar_uv(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3, 2) UVs of a plane in the x–z plane (normal +y): u = 0 → 1 along +x, v = 0 → 1 along −z (the
    image upright when seen from above with −z away), over the plane's extent."""
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    span = np.where(high > low, high - low, 1.0)
    corners = vertices[faces]
    return np.stack([(corners[..., 0] - low[0]) / span[0], (high[2] - corners[..., 2]) / span[2]], axis=-1)


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


def cylinder_uv(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3, 2) UVs of a cylinder about z: the side u = longitude / 2π, v = 0 → 1 from bottom to top; each cap
    the map seen along z over the disc's square (u along +x, v along +y)."""
    corners = vertices[faces]
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    span = np.where(high > low, high - low, 1.0)
    side = sphere_uv(vertices, faces)[..., 0]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    cap = np.abs(normal[:, 2]) > 0.5 * np.linalg.norm(normal, axis=1)
    u = np.where(cap[:, None], (corners[..., 0] - low[0]) / span[0], side)
    v = np.where(cap[:, None], (corners[..., 1] - low[1]) / span[1], (corners[..., 2] - low[2]) / span[2])
    return np.stack([u, v], axis=-1)


def torus_uv(vertices: np.ndarray, faces: np.ndarray, major_radius: float) -> np.ndarray:
    """(F, 3, 2) UVs of a torus about z: u = the angle around z / 2π, v = the angle around the tube / 2π
    (0 on the outer equator, rising toward +z), both continuous across their seams within a face."""
    corners = vertices[faces]
    u = (np.arctan2(corners[..., 1], corners[..., 0]) / (2 * np.pi)) % 1.0
    ring = np.hypot(corners[..., 0], corners[..., 1]) - major_radius
    v = (np.arctan2(corners[..., 2], ring) / (2 * np.pi)) % 1.0
    return np.stack([_seamless(u), _seamless(v)], axis=-1)
