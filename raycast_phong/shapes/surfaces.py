"""What several built-in kinds share: surfaces of revolution about z, and texture coordinates by longitude and
latitude. Every shape is centred on the origin; revolved shapes turn about z."""

from __future__ import annotations

import numpy as np


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
    u = _seamless(np.where(pole, np.nan, u))  # a pole corner's NaN is left out of its face's mean
    u = np.where(pole, np.nanmean(u, axis=1, keepdims=True), u)
    return np.stack([u, v], axis=-1)
