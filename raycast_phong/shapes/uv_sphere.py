"""uv_sphere: a sphere of latitude rings and longitude steps, as trimesh counts them."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from ..values.fields import KindKeys, Length, Segments
from .kind import Revolved
from .surfaces import revolve, sphere_uv


def uv_sphere(segments) -> tuple[np.ndarray, np.ndarray]:
    """Unit UV sphere as trimesh counts it: segments (a, b) give a (rounded up to even) latitude points from
    pole to pole and 2b (b rounded up to even) longitude steps."""
    latitude, longitude = (s + s % 2 for s in segments)
    theta = np.linspace(0.0, np.pi, latitude)
    radius = np.sin(theta)
    radius[[0, -1]] = 0.0  # the poles (sin π is 1.2e-16, not 0)
    return revolve(radius, -np.cos(theta), 2 * longitude)


class UvSphereKeys(KindKeys):
    """A sphere of latitude and longitude lines, its poles on the local z axis."""
    radius: Length = Field(1.0, description="the radius")
    segments: Segments | None = Field(None, description=(
        "[a, b]: a points from pole to pole, 2b steps around, each rounded up to even (trimesh's count); default "
        "[32, 16]"))


class UvSphere(Revolved):
    name = "uv_sphere"
    keys = UvSphereKeys

    def lengths(self, obj):
        return (obj.radius,)

    def unit_mesh(self, obj, unit):
        return uv_sphere(obj.segments or (32, 16))

    def triangles(self, obj):
        # trimesh rounds both counts up to even and doubles the second; 2 triangles fewer per meridian at the poles.
        rings, sections = (c + c % 2 for c in (obj.segments or (32, 16)))
        return 2 * (rings - 2) * 2 * sections

    def uv(self, obj, vertices, faces):
        return sphere_uv(vertices, faces)

    def exact_normals(self, obj, corners, flat):
        return corners  # p / |p|
