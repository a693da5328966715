"""The built-in kinds of object, one module each, and the registry every caller asks (`KINDS`, `kind_of`).

Each kind builds the triangles trimesh.creation builds (same positions to float64 rounding, same faces and
orientation, another order), so images rendered before keep their references; trimesh itself is imported only for
mesh files. Nothing is cleaned afterwards: a point on the axis of revolution is one vertex by construction, and
only the triangles that would join it to itself are left out (trimesh instead merges vertices closer than 1e-8
and drops revolved triangles of area below 1e-8, which opens holes near the poles of a fine uv sphere). Every
shape is centred on the origin; revolved shapes turn about z.

A mesh file (mesh.py) is a kind too, the one read rather than built (ShapeKind.from_file).

Adding a kind: a module here with its keys (a values.fields.KindKeys model: each key with its default and bounds)
and a ShapeKind subclass naming them, and its line in KINDS; nothing else (docs/pipeline.md's worked cone). The
scene schema gathers the keys from KINDS, so this package imports nothing of the scene but its value types.
"""

from __future__ import annotations

from .box import Box, box, box_uv
from .cylinder import Cylinder, cylinder, cylinder_uv
from .icosphere import Icosphere, icosahedron, icosphere
from .kind import THIN, ShapeKind, subdivided
from .mesh import Mesh
from .plane import Plane, planar_uv, plane_mesh
from .surfaces import revolve, sphere_uv
from .torus import Torus, torus, torus_uv
from .uv_sphere import UvSphere, uv_sphere

MESH = Mesh()  # the one kind read from a file, not built (last: the scene format lists it after the shapes)
KINDS: dict[str, ShapeKind] = {kind.name: kind for kind in (Icosphere(), UvSphere(), Box(), Plane(), Cylinder(),
                                                               Torus(), MESH)}


def kind_of(obj) -> ShapeKind:
    """The kind of a scene object."""
    return KINDS[obj.shape]


def from_file(obj) -> bool:
    """Whether a scene object is read from a file (its kind's from_file: a mesh), not built."""
    return KINDS[obj.shape].from_file


__all__ = ["KINDS", "MESH", "THIN", "Mesh", "ShapeKind", "box", "box_uv", "cylinder", "cylinder_uv", "from_file",
           "icosahedron", "icosphere", "kind_of", "planar_uv", "plane_mesh", "revolve", "sphere_uv", "subdivided",
           "torus", "torus_uv", "uv_sphere"]
