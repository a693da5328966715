"""The regular-expression reading of an OBJ's concave polygons that io/meshes/obj_polygons.py's compiled scan replaced,
kept as the tests' oracle: for LF text of well-formed records, the scan must find the same concave polygons and
cut them into the same lines. The ear clipping both share (unchanged) is imported from the package."""

from __future__ import annotations

import re

import numpy as np

from raycast_phong.io.meshes.polygons import ear_clip

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
        triangles = ear_clip(points[concave[k]])
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
