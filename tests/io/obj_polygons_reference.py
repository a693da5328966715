"""The regular-expression reading of an OBJ's concave polygons that io/obj_polygons.py's compiled scan replaced,
kept as the tests' oracle (imports nothing of the package): for LF text of well-formed records, the scan must
cut the same polygons into the same lines."""

from __future__ import annotations

import re

import numpy as np

POLYGON = re.compile(rb"^[ \t]*f(?:[ \t]+[^ \t\r\n#]+){4,}[ \t]*(?:#[^\r\n]*)?$", re.MULTILINE)
VERTEX = re.compile(rb"^[ \t]*v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)", re.MULTILINE)


def triangulate_concave(data: bytes) -> tuple[bytes, int]:
    """The OBJ text with every concave polygon cut into triangles, and how many polygons were cut.

    Convexity is tested for all polygons of one corner count at once (90,000 quads: about a second); only
    the concave ones are cut, one by one."""
    polygons = list(POLYGON.finditer(data))
    if not polygons:
        return data, 0
    found = list(VERTEX.finditer(data))
    try:
        points = np.array([m.groups() for m in found]).astype(np.float64).reshape(-1, 3)
    except ValueError:
        return data, 0  # trimesh words what is wrong with the file
    if not len(points):
        return data, 0  # faces without vertices: the reader reports the indices out of range
    starts = np.array([m.start() for m in found], np.int64)
    before = np.searchsorted(starts, np.array([m.start() for m in polygons], np.int64))  # v lines before: -1's base
    tokens = [m.group(0).split(b"#", 1)[0].split()[1:] for m in polygons]
    groups: dict[int, list[int]] = {}
    for k, words in enumerate(tokens):
        groups.setdefault(len(words), []).append(k)
    concave: dict[int, np.ndarray] = {}
    for members in groups.values():
        try:
            index = np.array([[int(t.split(b"/", 1)[0]) for t in tokens[k]] for k in members], np.int64)
        except ValueError:
            continue  # the reader reports a malformed face
        index = np.where(index < 0, before[members][:, None] + index, index - 1)
        valid = ((index >= 0) & (index < len(points))).all(axis=1)  # the reader reports indices out of range
        bent = valid & ~_convex(points[np.clip(index, 0, max(len(points) - 1, 0))])
        concave.update({members[i]: index[i] for i in np.flatnonzero(bent)})
    pieces, at, cut = [], 0, 0
    for k in sorted(concave):
        triangles = _ear_clip(points[concave[k]])
        if triangles is None:
            continue
        match = polygons[k]
        lines = b"\n".join(b"f " + b" ".join(tokens[k][c] for c in triangle) for triangle in triangles)
        pieces += [data[at:match.start()], lines]
        at, cut = match.end(), cut + 1
    if not cut:
        return data, 0
    pieces.append(data[at:])
    return b"".join(pieces), cut


def _convex(corners: np.ndarray) -> np.ndarray:
    """(m,) bool: which of m polygons (m, n, 3) turn the same way at every corner about their own normal
    (Newell's: the sum of the cross products about the centre); one without a normal counts as convex."""
    centred = corners - corners.mean(axis=1, keepdims=True)
    normal = np.cross(centred, np.roll(centred, -1, axis=1)).sum(axis=1)
    edges = np.roll(corners, -1, axis=1) - corners
    turns = np.einsum("mij,mj->mi", np.cross(edges, np.roll(edges, -1, axis=1)), normal)
    scale = np.abs(turns).max(axis=1, keepdims=True)
    return (turns >= -1e-12 * scale).all(axis=1) | ~(np.linalg.norm(normal, axis=1) > 0)


def _ear_clip(corners: np.ndarray) -> list[tuple[int, ...]] | None:
    """Triangles (corner numbers, wound as the polygon) of a concave polygon (n, 3), or None when it cannot
    be cut (no plane, or earcut leaves it: trimesh's fan then stays)."""
    import mapbox_earcut

    normal = np.cross(corners - corners.mean(axis=0), np.roll(corners, -1, axis=0) - corners.mean(axis=0)).sum(axis=0)
    length = np.linalg.norm(normal)
    if not length > 0:
        return None
    normal /= length
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    flat = np.column_stack([corners @ u, corners @ np.cross(normal, u)])  # counter-clockwise about the normal
    found = mapbox_earcut.triangulate_float64(flat, np.array([len(flat)], np.uint32)).reshape(-1, 3)
    if not len(found):
        return None
    a, b, c = flat[found[:, 0]], flat[found[:, 1]], flat[found[:, 2]]
    clockwise = ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])) < 0
    found[clockwise] = found[clockwise][:, ::-1]  # wound as the polygon: counter-clockwise about its normal
    return [tuple(int(k) for k in triangle) for triangle in found]
