"""The scene's colour maps, each decoded once (io/textures.py) and only when a face's material uses it."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..codes import MAP_COLUMNS
from ..errors import SceneError
from ..records import Texture
from ..scene.schema import Scene
from .memo import FRESH, Memo, file_stamp

if TYPE_CHECKING:
    from ..io.meshes.read import MeshFile


class TextureBank:
    """The scene's decoded textures, each decoded once and only when a face's material uses it (a file's
    unused maps are never decoded), as the scene's render.colour asks (io.textures: as stored, or decoded from
    sRGB to linear values); a map that cannot be decoded is a note and its factor stands alone."""

    def __init__(self, scene: Scene, memo: Memo = FRESH):
        self.scene, self.memo = scene, memo
        self.textures: list[Texture] = []
        self.notes: list[str] = []
        self.found: dict = {}

    def add(self, key, decode, wrap_s: str, wrap_t: str, name: str, stamp) -> int:
        """The texture row of `key`, decoded by `decode()` the first time; -1 (and a note) if it cannot be.
        `stamp()` (a file's version, or the image object a mesh file holds) lets a memo keep the pixels."""
        if key not in self.found:
            try:
                pixels = self.memo.texture((*key, self.scene.render.colour), stamp, decode)
            except SceneError:
                raise  # a scene's own map: the scene is wrong (one line, exit 2)
            except ValueError as error:
                self.notes.append(f"{name} cannot be decoded as an image ({error}); its factor is used")
                self.found[key] = -1
            else:
                self.found[key] = len(self.textures)
                self.textures.append(Texture(pixels, wrap_s, wrap_t, name))
        return self.found[key]

    def file_map(self, read: MeshFile, index: int) -> int:
        """The texture row of a mesh file's map `index` (into read.texture_sources), -1 for none."""
        if index < 0:
            return -1
        from ..io.textures import decode_file, decode_pil
        found = read.texture_sources[index]
        colour, channel = self.scene.render.colour, found.channel
        on_disk = isinstance(found.source, Path)  # a file, or an image object the mesh file holds
        key = (str(found.source) if on_disk else id(found.source), found.wrap_s, found.wrap_t, channel)
        decode = lambda: (decode_file if on_disk else decode_pil)(found.source, colour, channel)
        stamp = lambda: file_stamp(found.source) if on_disk else found.source
        return self.add(key, decode, found.wrap_s, found.wrap_t, found.name, stamp)

    def scene_map(self, name: str, key: str) -> int:
        """The texture row of a scene material's map (its `kd_map`, ...), -1 for none; SceneError (one line)
        when the file is missing or not an image."""
        material = self.scene.materials.get(name)
        value = getattr(material, key, None) if material is not None else None
        if value is None:
            return -1
        from ..io.textures import decode_scene_map
        path, wrap = self.scene.resolve(value.path), value.wrap
        where = self.scene.origin.at("materials", name, key)
        return self.add((str(path), wrap, wrap), lambda: decode_scene_map(path, where, self.scene.render.colour),
                        wrap, wrap, str(path), lambda: file_stamp(path))

    def maps_of(self, material, read: MeshFile | None = None) -> tuple[int, int, int]:
        """(ka, kd, ke) texture rows of a material: a FileMaterial of `read`, or a scene material by name;
        the k_a map is the k_d map unless a k_a map of its own is given (the texture modulates both)."""
        if read is not None:
            ka, kd, ke = (self.file_map(read, i) for i in (material.ka_map, material.kd_map, material.ke_map))
        else:
            name = next((n for n, m in self.scene.materials.items() if m is material), None)
            if name is None:
                return -1, -1, -1
            ka, kd, ke = (self.scene_map(name, k) for k in MAP_COLUMNS)
        return (kd if ka < 0 else ka), kd, ke

    def scene_maps(self, used: list[str]) -> np.ndarray:
        """(1 + scene materials, 3) texture rows of the default's and the scene's materials; decoded only for
        the materials some object uses; empty when none has a map."""
        rows = np.full((1 + len(self.scene.materials), 3), -1, np.int64)
        used = set(used)
        for i, (name, material) in enumerate(self.scene.materials.items()):
            if name in used or name == "default":
                rows[1 + i] = self.maps_of(material)
        return rows if (rows >= 0).any() else np.full((0, 3), -1, np.int64)
