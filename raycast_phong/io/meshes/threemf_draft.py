"""The 3MF 0.93 draft's colours, materials and textures (namespace .../3dmanufacturing/2013/01), told in the
core 1.0 Materials extension's terms, so that threemf.py colours the triangles as it does a 1.0 file's.

The draft (as its published samples and lib3mf's reader use it) has resources

    <color id="C" value="#RRGGBB"/>  or  value="tex(T)"     a colour, or texture T's image
    <material id="M" name="..." colorid="C"/>              a material shown in colour C
    <texture id="T" path="/3D/Texture/..." contenttype=.../>

and, in a mesh, `<texturevertices><texturevertex u v/>...`; a triangle or an object names `colorid` (one id,
three ids "a,b,c" for its corners, or "tex(T)") or `materialid`, and a textured triangle `cv1 cv2 cv3`, indices
of its object's texture vertices (u right, v up, as 1.0's tex2coord). Told as: every plain colour a row of one
colour group, each material a base of one base group, each texture a texture2d, each object's texture vertices a
texture2dgroup per texture it uses.
"""

from __future__ import annotations

import posixpath
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import FileProblem

NAMESPACE = "http://schemas.microsoft.com/3dmanufacturing/2013/01"
TAGS = ("color", "material", "texture", "texturevertex")  # the draft's own elements threemf.py's parse yields
# The ids of the groups made here: below -1 (a file's ids are 0 .. 2^31 - 1; -1 is "none"), as threemf.py's
# property ids are int64: the colours -2, material M -2^40 - M, object k's texture T -2^50 - k 2^31 - T.
COLOURS = "-2"
TEXTURE = "draft texture "  # a texture2d's key (a string: no triangle names it)


def _material(identity: str) -> str:
    return str(-(1 << 40) - int(identity))


def _uv(objects: int, texture: str) -> str:
    return str(-(1 << 50) - (objects << 31) - int(texture))


@dataclass
class Draft:
    """What a draft part has defined so far, and the current object's texture vertices."""
    path: Path
    colours: list = field(default_factory=list)      # (3,) sRGB rows of the plain colours
    rows: dict = field(default_factory=dict)         # colour id → its row
    textured: dict = field(default_factory=dict)     # colour id → texture id (a "tex(T)" colour)
    uv: list = field(default_factory=list)           # the current object's (u, v) words
    used: set = field(default_factory=set)           # texture ids the current object's triangles use
    objects: int = 0

    def resource(self, properties: dict, name: str, attrib, colour) -> None:
        """A <color>, <material> or <texture> into `properties` (threemf's _Model.properties); `colour` reads
        #RRGGBB as threemf does."""
        identity = attrib.get("id")
        if name == "texture":
            member = posixpath.normpath((attrib.get("path") or "").lstrip("/"))
            properties[TEXTURE + str(identity)] = ("texture", member, "repeat", "repeat")
        elif name == "color":
            value = (attrib.get("value") or "").strip()
            if value.startswith("tex("):
                self.textured[identity] = self._texture_id(value)
            else:
                self.rows[identity] = len(self.colours)
                self.colours.append(colour(value, self.path))
                properties[COLOURS] = ("colour", np.array(self.colours, np.float64).reshape(-1, 3))
        elif name == "material":
            found = self.rows.get(attrib.get("colorid"))
            rgb = self.colours[found] if found is not None else (1.0, 1.0, 1.0)  # a textured or missing colour
            name = attrib.get("name") or f"material {identity}"
            properties[_material(self._id(identity, "material id"))] = ("base", [name], np.array([rgb], np.float64))

    def texture_vertex(self, attrib) -> None:
        self.uv.append((attrib.get("u"), attrib.get("v")))

    def triangle(self, attrib) -> tuple:
        """(pid, p1, p2, p3) of a draft triangle, in the groups made here (None where it names none)."""
        return self._property(attrib.get("colorid"), attrib.get("materialid"),
                              tuple(attrib.get(f"cv{k}") for k in (1, 2, 3)))

    def object_end(self, properties: dict, attrib: dict, numbers) -> dict:
        """The object's attributes with its draft colorid/materialid told as pid and pindex; the texture groups
        its triangles use made from its texture vertices (`numbers` parses them as threemf does)."""
        pid, first, *_ = self._property(attrib.get("colorid"), attrib.get("materialid"), (None, None, None))
        if pid is not None:
            attrib = {**attrib, "pid": pid, "pindex": first or "0"}
        if self.used:
            uv = numbers(self.uv, np.float64, "texturevertex", self.path).reshape(-1, 2)
            for texture in self.used:
                properties[_uv(self.objects, texture)] = ("uv", TEXTURE + texture, uv)
        self.uv, self.used, self.objects = [], set(), self.objects + 1
        return attrib

    def _property(self, colour: str | None, material: str | None, corners: tuple) -> tuple:
        if colour:
            colour = colour.strip()
            texture = self._texture_id(colour) if colour.startswith("tex(") else self.textured.get(colour)
            if texture is not None:
                self.used.add(texture)
                return (_uv(self.objects, texture), *corners)
            ids = [word.strip() for word in colour.split(",")]
            rows = [self.rows.get(word) for word in ids]
            if len(ids) not in (1, 3) or None in rows:
                raise FileProblem(f"{str(self.path)!r}: a 0.93 draft colorid {colour[:40]!r} names no plain colour; "
                                  "allowed: the id of a <color>, three ids 'a,b,c', or tex(N)")
            rows = rows * 3 if len(rows) == 1 else rows
            return (COLOURS, *(str(row) for row in rows))
        if material:
            return (_material(self._id(material.strip(), "materialid")), "0", None, None)
        return (None, *corners)

    def _texture_id(self, value: str) -> str:
        return self._id(value[4:].rstrip(")").strip(), f"colour {value[:40]!r}")

    def _id(self, word, what: str) -> str:
        """A resource id: digits, below 2^31 (core's ST_ResourceID)."""
        if not (isinstance(word, str) and word.isdigit() and int(word) < 1 << 31):
            raise FileProblem(f"{str(self.path)!r}: a 0.93 draft {what} names id {str(word)[:40]!r}; allowed: a "
                              "resource id 0 .. 2147483647")
        return word
