"""The one interface every built-in kind of object has (`ShapeKind`): its keys (the scene schema's model of them),
and what the renderer, the memory estimate, the plan's advice and the accuracy study ask of a shape. Each kind is
one module of this package; the registry (`shapes.KINDS`) is the only list of them.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from ..errors import Problem
from ..values.fields import KindKeys

THIN = 2.0 ** -23  # float32's resolution: a tube thinner than this share of the shape collapses in Embree's frame


class ShapeKind:
    """A built-in kind of object. A subclass states its name, its own keys (`keys`: their defaults and bounds, which
    the scene schema validates), the key that sets its size, and builds its triangles at unit size (`unit_mesh`);
    the rest has defaults that fit a closed, curved shape."""
    name: ClassVar[str]
    keys: ClassVar[type[KindKeys]] = KindKeys  # the keys it alone reads (none: only the keys of every object)
    size_key: ClassVar[str] = "segments"   # the scene key that sets its triangle count (the memory advice)
    curved: ClassVar[bool] = True          # a highlight can be narrower than a pixel on it (flat faces: no)
    thin_key: ClassVar[str | None] = None  # the length that must stay above float32's resolution of the whole
    max_level: ClassVar[int] = 9           # the finest tessellation level the scene format allows (segments ≤ 4096)
    from_file: ClassVar[bool] = False      # read from a file (shapes/mesh.py), not built: no closed form, no levels

    def lengths(self, obj) -> tuple[float, ...]:
        """Its lengths: it is built at unit size (the largest length) and scaled after, so a shape of radius 1e-20
        or 1e15 has the same well-scaled triangles."""
        raise NotImplementedError

    def unit_mesh(self, obj, unit: float) -> tuple[np.ndarray, np.ndarray]:
        """Vertices (V, 3) float64 and faces (F, 3) int64, closed and wound outward, at lengths / unit."""
        raise NotImplementedError

    def triangles(self, obj) -> int:
        """How many triangles `template` makes (the memory estimate counts before building)."""
        raise NotImplementedError

    def template(self, obj) -> tuple[np.ndarray, np.ndarray]:
        """The object's triangles in its own frame, at its size; a Problem (one line; geometry.templates places
        it at the object) when a tube is too thin for Embree's float32 to hit."""
        lengths = self.lengths(obj)
        unit = max(lengths)
        thin = getattr(obj, self.thin_key) if self.thin_key else unit
        if thin < THIN * unit:
            raise Problem(f"a {obj.shape} with lengths {list(lengths)} has no triangles Embree can hit: its "
                          f"{self.thin_key} is below float32's resolution of its size; allowed: at least "
                          f"{THIN:.3g} of the larger length")
        vertices, faces = self.unit_mesh(obj, unit)
        return vertices * unit, faces

    def uv(self, obj, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(F, 3, 2) texture coordinates of the template's face corners."""
        raise NotImplementedError

    def exact_normals(self, obj, corners: np.ndarray, flat: np.ndarray) -> np.ndarray:
        """The true surface direction at every face corner (F, 3, 3), not yet of unit length, in the object's frame
        (`normals = "exact"`); `flat` repeats each face's unit normal. Flat faces: the face normal, which is exact."""
        return flat

    def refined(self, obj, level: int) -> dict:
        """The keys that give tessellation `level` (docs/accuracy.md, "Levels"); L = 2 is the format's default."""
        return {}

    def level_of(self, obj) -> int:
        """The level of the object as the scene gives it (the inverse of `refined`)."""
        return 0

    def finer(self, obj, more: int) -> str:
        """How to make its triangles `more` subdivision steps finer (the plan's Gouraud advice)."""
        return subdivided(more)


class Revolved(ShapeKind):
    """A surface of revolution about z (surfaces.revolve) whose `segments` are [steps around z, steps along its
    profile]: level L has 8·2^L steps around and 4·2^L along (L = 2 is the format's default [32, 16])."""

    def refined(self, obj, level):
        return {"segments": [8 * 2 ** level, 4 * 2 ** level]}

    def level_of(self, obj):
        return doublings((obj.segments or (32, 16))[0], 8)


def doublings(count: int, first: int) -> int:
    """The level L whose segment count first·2^L is nearest `count` (0 at the least): `refined`'s inverse for the
    kinds whose levels double their first segment count."""
    return max(0, round(math.log2(count / first)))


def subdivided(more: int) -> str:
    """The advice for any triangles (a mesh file's, or a kind with no key of its own for it)."""
    return f"{more} more subdivision(s) of each face (×{4 ** more} triangles)"
