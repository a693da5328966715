"""The material table's rows of the mesh files' own materials and vertex colours (FileRows), after the scene's."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..codes import ALPHA, ALPHA_CUTOFF, ALPHA_MAP, OPAQUE_ALPHA
from ..scene.schema import DEFAULT_MATERIAL, Scene
from .materials import material_rows, rows_of
from .textures import TextureBank

if TYPE_CHECKING:
    from ..io.meshes.read import MeshFile


def first_file_row(scene: Scene) -> int:
    """The material table's row of the first file material: after the default's and the scene's own."""
    return 1 + len(scene.materials)


class FileRows:
    """The material table's rows after the scene's own: one per file material of the mesh files' faces, and
    for faces with vertex colours but no material one whose k_a = k_d = 1 (the colours, which multiply k_a
    and k_d per corner in the kernel, then replace them). A file material the scene defines by name
    ([materials.NAME]) uses the scene's factors instead, and the file's maps unless it gives its own."""

    def __init__(self, scene: Scene, bank: TextureBank):
        self.scene, self.bank = scene, bank
        self.rows: list[np.ndarray] = []
        self.mapped = False
        self.first = first_file_row(scene)

    def faces(self, read: MeshFile) -> np.ndarray:
        """(F,) int32 material rows for the faces of one mesh file."""
        default = self.scene.materials.get("default", DEFAULT_MATERIAL)
        named = [self.scene.materials.get(m.name, m) for m in read.materials] + [default]  # -1: no material
        group = np.where(read.face_group < 0, len(named) - 1, read.face_group)
        # A scene material of the file material's name (framing writes them so) gives the factors; the file's
        # maps stay unless it names maps of its own.
        maps = []
        for own, used in zip(read.materials, named):
            given = self.bank.maps_of(used) if used is not own else (-1, -1, -1)
            maps.append(given if max(given) >= 0 else self.bank.maps_of(own, read))
        maps.append(self.bank.maps_of(default))
        if read.corner_colour is not None:  # colours with no material replace k_a and k_d: a white row
            named.append(default.model_copy(update={"ka": (1.0, 1.0, 1.0), "kd": (1.0, 1.0, 1.0)}))
            maps.append(maps[-1])
            coloured = (read.face_group < 0) & (read.corner_colour[:, 0, 0] >= 0)
            group = np.where(coloured, len(named) - 1, group)
        self.mapped |= any(r >= 0 for m in maps for r in m)
        rows = rows_of(named, np.asarray(maps, np.int64).reshape(-1, 3))
        for row, own in enumerate(read.materials):  # alpha the file gives (glTF alphaMode MASK or BLEND)
            if own.alpha_cutoff != OPAQUE_ALPHA:
                rows[row, ALPHA_CUTOFF], rows[row, ALPHA] = own.alpha_cutoff, own.alpha
                rows[row, ALPHA_MAP] = self.bank.file_map(read, own.alpha_map)
                self.mapped |= rows[row, ALPHA_MAP] >= 0
        self.rows.append(rows)
        return (self.first + sum(len(r) for r in self.rows[:-1]) + group).astype(np.int32)

    def table(self) -> np.ndarray:
        return np.concatenate(self.rows) if self.rows else material_rows(*(np.zeros((0, 3)),) * 4, np.zeros(0))
