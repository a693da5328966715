"""Wavefront materials: the .mtl files an OBJ names (its `mtllib` statements) and what they say, on the
lecture's model (docs/meshes.md, "Materials"). Each .mtl is read and parsed once per version of its OBJ
(io/meshes/source.py keeps the result, ObjMaterials, for every stage that asks). No trimesh."""

from __future__ import annotations

import math
import re
from contextlib import suppress
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ...codes import MATERIAL_DEFAULTS
from ...errors import SceneError
from ..files import open_regular, shown_name
from .content import is_number
from .materials import FileMaterial, TextureSource, specular_lobe
from .materials import rgb as _rgb

MAX_SIDE_FILE = 16 << 20  # an .mtl is text of a few kB; refuse to read more than a scene file may be
TEXTURE_KEYS = ("map_", "bump", "disp", "decal", "refl", "norm")

MTLLIB = re.compile(rb"^[ \t]*mtllib[ \t]+([^\r\n]+)", re.MULTILINE)  # an OBJ's mtllib statement: its names


def uncommented(words: list) -> list:
    """A line's words before its comment: `#` starts one only at the start of a word, so a name holding `#`
    (Godot 4 writes `newmtl StandardMaterial3D#-92`) is whole, as in the OBJ specification's examples."""
    for k, word in enumerate(words):
        if word.startswith("#" if isinstance(word, str) else b"#"):
            return words[:k]
    return words


def mtllib_names(lines: list[bytes], folder: Path) -> list[str]:
    """The .mtl files named by an OBJ's `mtllib` statements (`lines`: each statement's text after `mtllib`),
    in order, each once. The OBJ specification lets one statement name several files: they are separated by
    blanks, a backslash escapes a space (`b\\ c.mtl` is "b c.mtl"), and a `#` word starts a comment. A
    statement whose whole text names a file beside the OBJ is that one file (`mtllib my model.mtl`, as exporters
    write it, unescaped)."""
    names = []
    for line in lines:
        text = line.decode("utf-8", "replace").strip()
        words = uncommented([word.replace("\\ ", " ") for word in re.split(r"(?<!\\)[ \t]+", text)])
        whole = text.replace("\\ ", " ")
        with suppress(OSError):  # a name too long to be one file: the words
            if len(words) > 1 and (folder / whole).is_file():
                words = [whole]
        names += words
    return list(dict.fromkeys(name for name in names if name))


def scan_mtllib(handle) -> list[bytes]:
    """The text after `mtllib` of each such statement of the open OBJ `handle` (read from its start), UTF-8
    (a line that is not is read as Latin-1, as the OBJ itself is). The file is scanned in 1 MB blocks, not
    held: `mtllib` may come anywhere, and more than once."""
    lines, carry = [], b""
    for block in iter(lambda: handle.read(1 << 20), b""):
        block = carry + block
        cut = block.rfind(b"\n") + 1  # whole lines only: a line split between two blocks waits
        if b"mtllib" in block[:cut]:  # find() at memory speed; the pattern only where it can match
            lines += MTLLIB.findall(block[:cut])
        carry = block[cut:][-4096:]  # an mtllib line is short: a longer remainder is no mtllib
    lines += MTLLIB.findall(carry)
    return [utf8(line) for line in lines]


def utf8(text: bytes) -> bytes:
    """`text` as UTF-8: itself, or read as Latin-1 when it is not (every byte is a Latin-1 character)."""
    try:
        text.decode("utf-8")
        return text
    except UnicodeDecodeError:
        return text.decode("latin-1").encode("utf-8")


class ObjMaterials(NamedTuple):
    """What an OBJ's .mtl files say, parsed once: the materials by name, the notes their reading gave, and the
    colour maps they name (FileMaterial's map indices count in `sources`)."""
    library: dict[str, FileMaterial]
    notes: tuple[str, ...]
    sources: tuple[TextureSource, ...]


def read_obj_materials(path: Path, names: list[str]) -> ObjMaterials:
    """The materials of every .mtl `names` gives (mtllib_names of the OBJ at `path`), by name: a name defined
    by several files keeps the first file's (the OBJ specification searches them in order). A missing or
    unreadable file is a note, and the others still count."""
    library: dict[str, FileMaterial] = {}
    notes: list[str] = []
    sources: list[TextureSource] = []
    for name in names:
        mtl = path.parent / name
        try:
            with open_regular(mtl, f"{path}: mtllib", "material file", MAX_SIDE_FILE) as handle:
                content = handle.read(MAX_SIDE_FILE + 1).decode("utf-8", "replace")
        except (SceneError, OSError) as error:
            why = "is missing" if isinstance(error, FileNotFoundError) else f"cannot be read ({error})"
            notes.append(f"{path}: its material file {name!r} {why}; the default material is used")
            continue
        for key, material in parse_mtl(content, mtl, notes, sources).items():
            library.setdefault(key, material)
    return ObjMaterials(library, tuple(notes), tuple(sources))


def parse_mtl(content: str, mtl: Path, notes: list[str],
              sources: list[TextureSource] | None = None) -> dict[str, FileMaterial]:
    """Wavefront .mtl → materials on the lecture's model (docs/meshes.md, "Materials").

    Ka → k_a, Kd → k_d, Ks → k_s, Ke → k_e, Ns → f; a key the material omits takes the scene default's
    value; illum 0 is colour only (k_e = Kd + Ke, the other terms 0), 1 has no specular term (k_s = 0),
    2 and above are Phong (reflection and refraction are out of scope). map_Kd, map_Ka and map_Ke are colour
    maps (appended to `sources`, found as _texture_path finds them, "-clamp on" clamps them, else they
    repeat); other maps (map_Ks, bump, ...) and d < 1 or Tr > 0 (transparency) are ignored, each said once.
    Coefficients outside [0, 1] are clamped, and said.
    """
    raw: dict[str, dict[str, list[str]]] = {}
    current = None
    for line in content.splitlines():
        words = uncommented(line.split())
        if len(words) < 2:
            continue
        key = words[0].lower()
        if key == "newmtl":
            current = raw.setdefault(" ".join(words[1:]), {})
        elif current is not None:
            current[key] = words[1:]
    materials, bad, clamped, textures, transparent, illums = {}, [], [], [], [], set()
    sources = [] if sources is None else sources
    registered: dict[tuple, int] = {}
    for name, keys in raw.items():
        values = {}
        for key in ("ka", "kd", "ks", "ke", "ns", "d", "tr", "illum"):
            if key not in keys:
                continue
            try:
                numbers = [float(word) for word in keys[key][:3]]
                if not all(math.isfinite(x) for x in numbers):
                    raise ValueError
            except ValueError:
                bad.append(f"{name}: {key.capitalize()} {' '.join(keys[key])}")
                continue
            values[key] = numbers
        textures += [(name, key, map_file(words)) for key, words in keys.items() if key.startswith(TEXTURE_KEYS)]
        if values.get("d", [1.0])[0] < 1 or values.get("tr", [0.0])[0] > 0:
            transparent.append(name)
        illum = int(values.get("illum", [2])[0])
        coefficients = {}
        for key in ("ka", "kd", "ks", "ke"):
            default = MATERIAL_DEFAULTS[key]
            given = values.get(key)
            rgb = default if given is None else (given * 3)[:3] if len(given) == 1 else given
            if any(not 0 <= x <= 1 for x in rgb):
                clamped.append(f"{name}: {key.capitalize()}")
            coefficients[key] = _rgb(np.clip(rgb, 0, 1))
        rows = {}
        for key in ("map_kd", "map_ka", "map_ke"):
            file = map_file(keys[key]) if key in keys else ""
            found = texture_path(mtl.parent, file) if file else None
            if found is None:
                continue  # missing: a note below, and the coefficient alone
            clamp = "clamp" if _map_clamps(keys[key]) else "repeat"
            if (found, clamp) not in registered:
                registered[(found, clamp)] = len(sources)
                sources.append(TextureSource(found, clamp, clamp, f"{mtl}: texture {file!r}"))
            rows[key] = registered[(found, clamp)]
        ks, shininess = specular_lobe(coefficients["ks"],
                                      values.get("ns", [MATERIAL_DEFAULTS["shininess"]])[0])
        coefficients["ks"] = _rgb(ks)
        if illum == 0:
            colour = np.clip(np.add(coefficients["kd"], coefficients["ke"]), 0, 1)
            coefficients = {"ka": (0.0,) * 3, "kd": (0.0,) * 3, "ks": (0.0,) * 3, "ke": _rgb(colour)}
        elif illum == 1:
            coefficients["ks"] = (0.0, 0.0, 0.0)
        elif illum > 2:
            illums.add(illum)
        kd_map = rows.get("map_kd", -1)
        ke_map = kd_map if illum == 0 else rows.get("map_ke", -1)  # colour only: the k_d map colours k_e
        materials[name] = FileMaterial(name, coefficients["ka"], coefficients["kd"], coefficients["ks"],
                                       coefficients["ke"], float(shininess), rows.get("map_ka", -1), kd_map, ke_map)
    if bad:
        notes.append(f"{mtl}: {len(bad)} value(s) are not numbers and keep their defaults (first: {bad[0]})")
    if clamped:
        notes.append(f"{mtl}: {len(clamped)} coefficient(s) outside [0, 1] are clamped to it (first: {clamped[0]})")
    if transparent:
        notes.append(f"{mtl}: transparency (d < 1 or Tr > 0) is ignored: material(s) "
                     f"{', '.join(map(repr, transparent))} render opaque")  # named: 'Windows render opaque' misread
    if illums:
        notes.append(f"{mtl}: illum {', '.join(map(str, sorted(illums)))} render as illum 2 (Phong); reflection "
                     "and refraction are out of scope")
    if textures:
        missing = sorted({file for _, _, file in textures if file and texture_path(mtl.parent, file) is None})
        notes.extend(f"{mtl}: texture {shown_name(file)} is missing" for file in missing)
        others = [f"{key} {file}" for _, key, file in textures if key not in ("map_kd", "map_ka", "map_ke")]
        if others:
            shown = ", ".join(others[:3]) + (", ..." if len(others) > 3 else "")
            notes.append(f"{mtl}: only colour maps (map_Kd, map_Ka, map_Ke) are applied; not applied: {shown}")
    return materials


# Options of a map statement and how many values each takes (the .mtl specification, "Texture map options").
MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
               "-mm": 2, "-o": 3, "-s": 3, "-t": 3, "-texres": 1, "-type": 1}


def map_file(words: list[str]) -> str:
    """The file a map statement names: its options skipped (-o, -s and -t take up to 3 numbers), the rest,
    spaces kept ("fuze uv.jpg"), backslashes read as folder separators (files written on Windows). Options
    come before the name (the .mtl specification), but some exporters write one after it (`wood.png -bm
    0.5`): words from an option to the end that are all options with their values are not part of the name."""
    at = 0
    while at < len(words) and words[at].lower() in MAP_OPTIONS:
        at = _past_values(words, at, len(words) - 1)
    end = next((i for i in range(at + 1, len(words)) if _only_options(words[i:])), len(words))
    return " ".join(words[at:end]).replace("\\", "/")


def _only_options(words: list[str]) -> bool:
    """Whether `words` are map options to the end, each with its values: one word for a one-value option
    (`-clamp on`, `-bm 0.5`), 1 to 3 numbers for -o, -s, -t, 1 or 2 for -mm."""
    at = 0
    while at < len(words):
        if words[at].lower() not in MAP_OPTIONS:
            return False
        end = _past_values(words, at, len(words))
        if end == at + 1:  # an option without its values
            return False
        at = end
    return True


def _past_values(words: list[str], at: int, stop: int) -> int:
    """Where the values of the map option words[at] end: one word for a one-value option, up to its count of
    numbers for the others, none at or past `stop`."""
    count, end = MAP_OPTIONS[words[at].lower()], at + 1
    while end - at - 1 < count and end < stop and (count == 1 or is_number(words[end])):
        end += 1
    return end


def texture_path(folder: Path, file: str) -> Path | None:
    """The texture a material names, relative to its .mtl: as written, else by its file name alone beside
    the .mtl (exporters often keep the absolute path of the machine they ran on); None when neither exists."""
    for candidate in (folder / file, folder / Path(file).name):
        with suppress(OSError):
            if candidate.is_file():
                return candidate
    return None


def _map_clamps(words: list[str]) -> bool:
    """Whether a map statement says "-clamp on" (the .mtl specification: texels outside [0, 1] clamp)."""
    lowered = [w.lower() for w in words]
    return any(w == "-clamp" and i + 1 < len(lowered) and lowered[i + 1] == "on" for i, w in enumerate(lowered))

