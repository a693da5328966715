"""Place a group's objects in the world (world = R (S v) + t, K objects at once) and give them face and corner
normals; refuse an object that leaves float32's range or collapses to a point.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..errors import SceneError
from ..scene.alike import placements
from ..scene.schema import Scene
from ..tolerances import POSITION_LIMIT
from .normals import _normalise_or, compute_corner_normals, face_normals, file_corner_normals
from .templates import ObjectMesh


class Part(NamedTuple):
    """Objects of one group, placed: K objects of n vertices and m faces each."""
    members: np.ndarray         # (K,) their indices in scene.objects, ascending
    vertices: np.ndarray        # (K, n, 3) float64, world
    faces: np.ndarray           # (K, m, 3) int64, each object's own vertex numbers (0..n-1), mirrored reversed
    unit: np.ndarray            # (K, m, 3) unit face normals
    corners: np.ndarray | None  # (K, m, 3, 3) corner normals in normal_dtype, or None


def place_group(scene: Scene, members: np.ndarray, template: ObjectMesh, exact: np.ndarray | None,
                vertex_normals: bool, normal_dtype: type,
                placed: Callable[[np.ndarray, np.ndarray], None] | None = None) -> Part:
    """Place K objects that share `template` (its vertices and faces in the object frame) and give them face
    and corner normals: the per-object steps of the scene format, done for all K at once. `placed(vertices,
    faces)`: told the placed vertices (K n, 3) and faces (K m, 3) (numbered across the K objects) once they are
    checked, before the normals are made."""
    scale, rotate, translate = placements(scene.objects, members)
    rotation = rotations_of(rotate)
    vertices = place_vertices(template.vertices, scale, rotation, translate, (rotate != 0).any(axis=1))
    mirrored = np.prod(scale, axis=1) < 0  # a mirroring scale reverses the winding so faces still point outward
    if len(members) == 1 and not mirrored[0]:  # one object (a mesh file): the template's faces, not a copy (no
        faces = np.ascontiguousarray(template.faces, np.int64)[None]  # one writes to a Part's faces)
    else:
        faces = np.broadcast_to(template.faces, (len(members), *template.faces.shape)).copy()
        faces[mirrored] = faces[mirrored][:, :, ::-1]
    # (K, 3) each, column by column (records.bounding_box: numpy reduces (K, n, 3) along n 15-25× slower than
    # three strided columns; 1.1M triangles' 556k vertices: 29 ms against 1 ms); no |v| copy.
    highest = np.stack([vertices[:, :, k].max(axis=1) for k in range(3)], axis=1)
    lowest = np.stack([vertices[:, :, k].min(axis=1) for k in range(3)], axis=1)
    reach = np.maximum(np.abs(highest), np.abs(lowest)).max(axis=1)  # max |v|; NaN stays NaN
    for k in np.flatnonzero(~(reach <= POSITION_LIMIT)):  # NaN fails the comparison too
        raise SceneError(f"placed (scale, rotate, translate), the object reaches a coordinate of {reach[k]:.3g}; "
                         f"allowed: within ±{POSITION_LIMIT:g}, so distances squared stay finite in float32; lower "
                         "scale, its size or translate", scene.origin.at("objects", int(members[k])))
    extent = highest - lowest
    for k in np.flatnonzero(~(extent != 0).any(axis=1)):
        obj = scene.objects[members[k]]
        raise SceneError(f"placed, the object collapses to a single point (its scale {list(obj.scale)} is below "
                         f"float64's resolution at translate {list(obj.translate)}); allowed: an object with some "
                         "extent; raise scale or its size", scene.origin.at("objects", int(members[k])))
    count, n = len(members), len(template.vertices)
    flat_vertices = vertices.reshape(-1, 3)
    flat_faces = faces[0] if count == 1 else (faces + (np.arange(count) * n)[:, None, None]).reshape(-1, 3)
    if placed is not None:
        placed(flat_vertices, flat_faces)
    unit, doubled_area = face_normals(flat_vertices, flat_faces)
    corners = None
    if vertex_normals:
        first = scene.objects[members[0]]
        if exact is not None:
            corners = place_normals(exact.reshape(-1, 3), scale, rotation).reshape(count, -1, 3, 3)
            corners[mirrored] = corners[mirrored][:, :, ::-1]  # as place() reversed the mirrored winding
            corners = corners.astype(normal_dtype, copy=False)
        elif template.normals is not None:
            placed = place_normals(template.normals, scale, rotation).reshape(-1, 3)
            corners = file_corner_normals(placed, flat_faces, unit, normal_dtype)
        else:
            crease = first.crease_angle if template.crease_angle is None else template.crease_angle
            corners = compute_corner_normals(flat_vertices, flat_faces, first.normals or "mean", crease,
                                             normal_dtype, normals=(unit, doubled_area))
        corners = corners.reshape(count, -1, 3, 3)
    del doubled_area
    return Part(members, vertices, faces, unit.reshape(count, -1, 3), corners)


def rotations_of(angles: list) -> np.ndarray:
    """(K, 3, 3) rotations about x, then y, then z, by K objects' angles in degrees. cos and sin come from the
    math module (the C library), whose bits numpy's vectorised ones need not share."""
    angles = np.asarray(angles, np.float64).reshape(-1, 3)
    distinct, inverse = np.unique(angles, return_inverse=True)
    cos = np.array([math.cos(math.radians(a)) for a in distinct.tolist()])[inverse].reshape(angles.shape)
    sin = np.array([math.sin(math.radians(a)) for a in distinct.tolist()])[inverse].reshape(angles.shape)
    turns = []
    for axis in range(3):
        i, j = (axis + 1) % 3, (axis + 2) % 3  # the plane it turns: y→z about x, z→x about y, x→y about z
        turn = np.broadcast_to(np.eye(3), (len(angles), 3, 3)).copy()
        turn[:, i, i] = turn[:, j, j] = cos[:, axis]
        turn[:, j, i], turn[:, i, j] = sin[:, axis], -sin[:, axis]
        turns.append(turn)
    return turns[2] @ turns[1] @ turns[0]


def place_vertices(vertices: np.ndarray, scale: np.ndarray, rotation: np.ndarray, translate: np.ndarray,
                   rotated: list[bool]) -> np.ndarray:
    """World = R (S v) + t for K objects sharing object-frame vertices (n, 3): (K, n, 3). An object neither
    turned nor scaled is only moved: the same numbers, and (n, 3) @ (3, 3) is slow for a large mesh. numpy's
    stacked matmul multiplies each object's pair as its own 2-D product does, so the bits do not depend on K."""
    placed = np.empty((len(scale), *vertices.shape))
    moved = ~np.asarray(rotated, bool) & (scale == 1).all(axis=1)
    if len(scale) == 1 and moved[0]:  # one object only moved (a mesh file): the same sums, no temporary
        np.add(vertices, translate[0], out=placed[0])
    elif moved.any():
        placed[moved] = vertices[None] + translate[moved][:, None, :]
    if not moved.all():
        turned = ~moved
        placed[turned] = (np.matmul(vertices[None] * scale[turned][:, None, :], rotation[turned].transpose(0, 2, 1))
                          + translate[turned][:, None, :])
    return placed


def place_normals(normals: np.ndarray, scale: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Object-frame normals (N, 3) → unit world normals (K, N, 3) for K objects; zero where one has no
    direction (the caller's fallback then applies). Normals transform with the inverse transpose:
    (R S)^-T = R S^-1, which stretches by at most 1/min|s|."""
    reach = (np.linalg.norm(normals, axis=-1, keepdims=True)[None]
             / np.abs(scale).min(axis=1)[:, None, None])
    # (n / s) @ R^T as three scaled columns of R: numpy's matmul with a 3-wide inner dimension took 95 ms for
    # 245,760 corners on a busy 2-core machine, this 4 ms.
    placed = sum(normals[None, :, k:k + 1] * (rotation[:, None, :, k] / scale[:, None, k:k + 1]) for k in range(3))
    return _normalise_or(placed, np.zeros_like(placed), reach)
