"""cylinder: a capped tube about z, centred: side quads and two cap fans."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from ..values.fields import KindKeys, Length, Segments
from .kind import Revolved
from .surfaces import revolve, sphere_uv


def cylinder(radius: float, height: float, sections: int) -> tuple[np.ndarray, np.ndarray]:
    """A capped cylinder about z of the given radius and height, centred; `sections` steps around."""
    half = height / 2.0
    return revolve(np.array([0.0, radius, radius, 0.0]), np.array([-half, -half, half, half]), sections)


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


class CylinderKeys(KindKeys):
    """A closed cylinder about its local z axis, centred on the origin."""
    radius: Length = Field(1.0, description="the radius")
    height: Length = Field(2.0, description="along its local z axis")
    segments: Segments | None = Field(None, description="[sections around, unused], default [32, 1]")


class Cylinder(Revolved):
    name = "cylinder"
    keys = CylinderKeys
    thin_key = "radius"

    def lengths(self, obj):
        return (obj.radius, obj.height)

    def unit_mesh(self, obj, unit):
        return cylinder(obj.radius / unit, obj.height / unit, (obj.segments or (32, 1))[0])

    def triangles(self, obj):
        return 4 * (obj.segments or (32, 1))[0]  # side quads and two cap fans

    def uv(self, obj, vertices, faces):
        return cylinder_uv(vertices, faces)

    def exact_normals(self, obj, corners, flat):
        """Radial (x, y, 0) on the side faces, ±z on the caps, decided per face by its face normal (the rim
        vertices are shared by both)."""
        unit = flat[:, 0]
        radial = np.concatenate([corners[..., :2], np.zeros_like(corners[..., 2:])], axis=-1)
        cap = np.abs(unit[:, 2]) > 0.5  # a cap face's normal is ±z, a side face's lies in the x–y plane
        return np.where(cap[:, None, None], np.sign(unit[:, None, 2:3]) * np.array([0.0, 0.0, 1.0]), radial)

    def refined(self, obj, level):  # the second value is unused, but the format asks for 3..4096
        return {"segments": [8 * 2 ** level, (obj.segments or (32, 3))[1]]}
