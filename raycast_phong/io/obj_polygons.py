"""An OBJ's polygons of four or more corners that are not convex, cut into triangles by ear clipping.

trimesh cuts every polygon as a fan from its first corner, which is right only for a convex polygon: a
concave one (a ring exported as one face with a bridge, an L-shaped panel) becomes triangles that cover
what the polygon leaves open. Here the OBJ text is rewritten before trimesh reads it: each concave
polygon's `f` line becomes one `f` line per triangle, cut by mapbox-earcut (which trimesh itself uses for
2-D polygons) in the polygon's own plane, each corner keeping its `v/vt/vn` token. Convex polygons and
triangles are left to trimesh's fan, which is the same for them. Only files with such polygons pay.
"""

from __future__ import annotations

import re

import numpy as np

POLYGON = re.compile(rb"^[ \t]*f(?:[ \t]+[^ \t\r\n#]+){4,}[ \t]*(?:#[^\r\n]*)?$", re.MULTILINE)
VERTEX = re.compile(rb"^[ \t]*v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)", re.MULTILINE)


def triangulate_concave(data: bytes) -> tuple[bytes, int]:
    """The OBJ text with every concave polygon cut into triangles, and how many polygons were cut."""
    polygons = list(POLYGON.finditer(data))
    if not polygons:
        return data, 0
    found = list(VERTEX.finditer(data))
    try:
        points = np.array([[float(x) for x in m.groups()] for m in found], np.float64).reshape(-1, 3)
    except ValueError:
        return data, 0  # trimesh words what is wrong with the file
    starts = np.array([m.start() for m in found], np.int64)
    pieces, at, cut = [], 0, 0
    for match in polygons:
        tokens = match.group(0).split(b"#", 1)[0].split()[1:]
        before = int(np.searchsorted(starts, match.start()))  # v lines before this face: the base of -1 indices
        try:
            index = np.array([int(t.split(b"/", 1)[0]) for t in tokens], np.int64)
        except ValueError:
            continue
        index = np.where(index < 0, before + index, index - 1)
        if not ((index >= 0) & (index < len(points))).all():
            continue  # the reader reports indices out of range
        triangles = _ear_clip(points[index])
        if triangles is None:
            continue
        lines = b"\n".join(b"f " + b" ".join(tokens[k] for k in triangle) for triangle in triangles)
        pieces += [data[at:match.start()], lines]
        at, cut = match.end(), cut + 1
    if not cut:
        return data, 0
    pieces.append(data[at:])
    return b"".join(pieces), cut


def _ear_clip(corners: np.ndarray) -> list[tuple[int, ...]] | None:
    """Triangles (corner numbers, wound as the polygon) of a concave polygon (n, 3), or None when it is convex
    (trimesh's fan is right) or cannot be cut (no plane, or earcut leaves it)."""
    import mapbox_earcut

    normal = np.cross(corners - corners.mean(axis=0), np.roll(corners, -1, axis=0) - corners.mean(axis=0)).sum(axis=0)
    length = np.linalg.norm(normal)
    if not length > 0:
        return None
    normal /= length
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    flat = np.column_stack([corners @ u, corners @ np.cross(normal, u)])  # counter-clockwise about the normal
    edges = np.roll(flat, -1, axis=0) - flat
    turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
    if (turns >= 0).all():
        return None  # convex: every corner turns left
    found = mapbox_earcut.triangulate_float64(flat, np.array([len(flat)], np.uint32)).reshape(-1, 3)
    if not len(found):
        return None
    a, b, c = flat[found[:, 0]], flat[found[:, 1]], flat[found[:, 2]]
    clockwise = ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])) < 0
    found[clockwise] = found[clockwise][:, ::-1]  # wound as the polygon: counter-clockwise about its normal
    return [tuple(int(k) for k in triangle) for triangle in found]
