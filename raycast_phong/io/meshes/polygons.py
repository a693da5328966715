"""Polygons of any size cut into triangles, one rule for every reader: a convex polygon as a fan from its
first corner, a concave one by ear clipping in its own plane.

A fan (0, j+1, j+2) covers a convex polygon exactly but fills a concave one's notch (an L-shaped panel, a
ring bridged into one face); the specifications allow concave polygons (Geomview's OFF: "The polygons may be
concave"; PLY and OBJ state no limit). Convexity is tested at once for all polygons of one size: a polygon
is convex when it turns the same way at every corner about its Newell normal n (the sum of the cross products
about its centre), turn_i = (e_i × e_i+1) · n ≥ −1e-12 max |turn|, e_i = c_i+1 − c_i. Only the concave ones
are cut one by one, by mapbox-earcut (which trimesh uses for 2-D polygons), and keep the fan's triangle count
(n − 2), so each triangle's polygon and order stay what the fan gave.
"""

from __future__ import annotations

import numpy as np

CHUNK = 1 << 16  # polygons tested at a time: the test's (P, n, 3) float64 temporaries stay a few MB each
CONVEX_TOLERANCE = 1e-12  # a turn this far below zero, relative to the polygon's largest, is still straight


def fan(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Polygons of `corners` corners each, cut as fans from their first corner: each triangle's polygon `row`, and
    its corner numbers `picks` (T, 3), (0, j + 1, j + 2) for triangle j of its fan; none for fewer than 3 corners."""
    fans = np.maximum(corners - 2, 0)
    row = np.repeat(np.arange(len(corners)), fans)
    step = np.arange(len(row)) - np.repeat(np.cumsum(fans) - fans, fans)
    return row, np.column_stack([np.zeros_like(step), step + 1, step + 2])


def listed(values: np.ndarray, first: np.ndarray, points: np.ndarray):
    """cut's vertex_of for polygons whose corner indices are the parsed numbers `values` from values[first] on:
    an index that cannot be a vertex is -1 (its polygon is not cut; the reader refuses it)."""
    def vertex_of(polygons: np.ndarray, k: int) -> np.ndarray:
        index = values[first[polygons] + k]
        return np.where(np.abs(index) <= len(points), index, -1).astype(np.int64)
    return vertex_of


def cut(corners: np.ndarray, vertex_of, points: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's polygon `row` and its three corner numbers `picks` (T, 3) within the polygon, for
    polygons of `corners` corners; `vertex_of(polygons, k)` gives corner k's vertex of those polygons, and
    `points` (V, 3) the vertices (None: fans only, when the positions are not at hand)."""
    row, picks = fan(corners)
    if points is None or not len(row):
        return row, picks
    first = np.cumsum(np.maximum(corners - 2, 0)) - np.maximum(corners - 2, 0)  # each polygon's first triangle
    for size in np.unique(corners[corners > 3]).tolist():
        every = np.flatnonzero(corners == size)
        for start in range(0, len(every), CHUNK):
            polygons = every[start:start + CHUNK]
            vertices = np.stack([vertex_of(polygons, k) for k in range(size)], axis=1)  # (P, n)
            usable = ((vertices >= 0) & (vertices < len(points))).all(axis=1)  # a bad index: the reader reports it
            polygons, vertices = polygons[usable], vertices[usable]
            concave = _concave(points[vertices]) if len(polygons) else np.zeros(0, bool)
            for polygon, corner in zip(polygons[concave].tolist(), vertices[concave]):
                triangles = ear_clip(points[corner])
                if triangles is not None and len(triangles) == size - 2:
                    picks[first[polygon]:first[polygon] + size - 2] = triangles
    return row, picks


def _concave(corners: np.ndarray) -> np.ndarray:
    """(P,) bool: which polygons (P, n, 3) turn both ways about their Newell normal (module docstring); one
    without a normal (degenerate, or not finite) is not concave: the fan stays."""
    with np.errstate(invalid="ignore", over="ignore"):
        centred = corners - corners.mean(axis=1, keepdims=True)
        normal = np.cross(centred, np.roll(centred, -1, axis=1)).sum(axis=1)
        edge = np.roll(corners, -1, axis=1) - corners
        turn = np.einsum("pkc,pc->pk", np.cross(edge, np.roll(edge, -1, axis=1)), normal)
        scale = np.abs(turn).max(axis=1, keepdims=True)
        bent = (turn < -CONVEX_TOLERANCE * scale).any(axis=1)
    return bent & np.isfinite(turn).all(axis=1) & ((normal * normal).sum(axis=1) > 0)


def ear_clip(corners: np.ndarray) -> np.ndarray | None:
    """Triangles (corner numbers (n − 2, 3), wound as the polygon) of a concave polygon (n, 3), or None when
    it cannot be cut (no plane, or earcut leaves it: the fan then stays)."""
    import mapbox_earcut

    normal = np.cross(corners - corners.mean(axis=0), np.roll(corners, -1, axis=0) - corners.mean(axis=0)).sum(axis=0)
    length = np.linalg.norm(normal)
    if not length > 0:
        return None
    normal /= length
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    flat = np.column_stack([corners @ u, corners @ np.cross(normal, u)])  # counter-clockwise about the normal
    found = mapbox_earcut.triangulate_float64(flat, np.array([len(flat)], np.uint32)).reshape(-1, 3).astype(np.int64)
    if not len(found):
        return None
    a, b, c = flat[found[:, 0]], flat[found[:, 1]], flat[found[:, 2]]
    clockwise = ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])) < 0
    found[clockwise] = found[clockwise][:, ::-1]  # wound as the polygon: counter-clockwise about its normal
    return found
