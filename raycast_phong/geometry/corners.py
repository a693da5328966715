"""Per-corner values of every face in the scene's order: texture coordinates and vertex colours, from each
group's template, reversed for a mirrored object as its winding is."""

from __future__ import annotations

import numpy as np

from ..scene.alike import placements
from ..scene.schema import Scene
from .templates import OBJECT_CHUNK_VERTICES, shape_uv


def _object_corners(scene: Scene, built: list, mesh, per_object, width: int, fill: float) -> np.ndarray:
    """(F, 3, width) float32 per-corner values of every face in the scene's order: `per_object(members,
    template)` gives a template's (m, 3, width) array or None (then `fill`); mirrored objects reversed."""
    if len(scene.objects) == 1:  # one object (a large mesh file): its own array, no copy
        members, template = built[0][0], built[0][1]
        values = per_object(members, template)
        if values is not None and np.prod(scene.objects[0].scale) >= 0:
            return np.ascontiguousarray(values, np.float32)
    out = np.full((int(mesh.face_count.sum()), 3, width), fill, np.float32)
    for members, template, *_ in built:
        values = per_object(members, template)
        if values is None:
            continue
        step = max(1, OBJECT_CHUNK_VERTICES // max(1, len(values)))
        for at in range(0, len(members), step):
            chunk = members[at:at + step]
            (scale,) = placements(scene.objects, chunk, ("scale",))
            mirrored = np.prod(scale, axis=1) < 0
            for objects, placed in ((chunk[~mirrored], values), (chunk[mirrored], values[:, ::-1])):
                rows = (mesh.face_start[objects][:, None] + np.arange(len(values))).ravel()
                out[rows] = np.broadcast_to(placed, (len(objects), *placed.shape)).reshape(-1, 3, width)
    return out


def corner_uvs(scene: Scene, built: list, mesh) -> np.ndarray:
    """(F, 3, 2) texture coordinates of every face: a mesh file's, or a built-in shape's (shape_uv)."""
    def uvs(members, template):
        if template.uv is not None or template.file is not None:
            return template.uv
        return shape_uv(scene.objects[members[0]], template.vertices, template.faces)
    return _object_corners(scene, built, mesh, uvs, 2, 0.0)


def corner_colours(scene: Scene, built: list, mesh, in_place: bool = True) -> np.ndarray:
    """(F, 3, 3) vertex colours per corner (1 where a face has none), or empty when no used file has any.
    `in_place`: the file's own array is changed (no copy); not when a memo keeps the file for the next build,
    whose material rows still tell the faces without colours by their -1."""
    def colours(members, template):
        read = template.file
        if read is None or read.corner_colour is None or scene.objects[members[0]].material != "default":
            return None
        colours = read.corner_colour  # the file's own array: -1 (a part without colours) becomes 1
        if not in_place:
            return np.where(colours < 0, np.float32(1), colours).astype(colours.dtype, copy=False)
        colours[colours < 0] = 1
        return colours
    if not any(t.file is not None and t.file.corner_colour is not None
               and scene.objects[m[0]].material == "default" for m, t, *_ in built):
        return np.zeros((0, 3, 3), np.float32)
    return _object_corners(scene, built, mesh, colours, 3, 1.0)
