"""torus: a tube of radius minor_radius around a circle of radius major_radius about z."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from ..values.fields import KindKeys, Length, Segments
from .kind import Revolved
from .surfaces import _seamless, revolve


def torus(major_radius: float, minor_radius: float, major_sections: int, minor_sections: int
          ) -> tuple[np.ndarray, np.ndarray]:
    """A torus about z: a tube of radius minor_radius whose centre circle has radius major_radius."""
    phi = np.linspace(0.0, 2.0 * np.pi, minor_sections + 1)[:-1]
    return revolve(minor_radius * np.cos(phi) + major_radius, minor_radius * np.sin(phi), major_sections,
                   closed=True)


def torus_uv(vertices: np.ndarray, faces: np.ndarray, major_radius: float) -> np.ndarray:
    """(F, 3, 2) UVs of a torus about z: u = the angle around z / 2π, v = the angle around the tube / 2π
    (0 on the outer equator, rising toward +z), both continuous across their seams within a face."""
    corners = vertices[faces]
    u = (np.arctan2(corners[..., 1], corners[..., 0]) / (2 * np.pi)) % 1.0
    ring = np.hypot(corners[..., 0], corners[..., 1]) - major_radius
    v = (np.arctan2(corners[..., 2], ring) / (2 * np.pi)) % 1.0
    return np.stack([_seamless(u), _seamless(v)], axis=-1)


class TorusKeys(KindKeys):
    """A torus about its local z axis."""
    major_radius: Length = Field(1.0, description="the radius of the tube's centre circle")
    minor_radius: Length = Field(0.25, description="the radius of the tube")
    segments: Segments | None = Field(None, description="[steps around z, steps around the tube], default [32, 16]")


class Torus(Revolved):
    name = "torus"
    keys = TorusKeys
    thin_key = "minor_radius"

    def lengths(self, obj):
        return (obj.major_radius, obj.minor_radius)

    def unit_mesh(self, obj, unit):
        major, minor = obj.segments or (32, 16)
        return torus(obj.major_radius / unit, obj.minor_radius / unit, major, minor)

    def triangles(self, obj):
        major, minor = obj.segments or (32, 16)
        return 2 * major * minor

    def uv(self, obj, vertices, faces):
        return torus_uv(vertices, faces, obj.major_radius)

    def exact_normals(self, obj, corners, flat):
        """p minus the nearest point of the tube's centre circle (radius major_radius in the x–y plane)."""
        ring = np.hypot(corners[..., 0], corners[..., 1])
        centre = obj.major_radius * corners[..., :2] / np.where(ring > 0, ring, 1.0)[..., None]
        return np.concatenate([corners[..., :2] - centre, corners[..., 2:]], axis=-1)
