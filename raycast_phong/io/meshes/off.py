"""OFF (Geomview's Object File Format), read by trimesh from its text: a file that is not UTF-8 is read as
Latin-1."""

from __future__ import annotations

from .format import Loaded, MeshFormat, Reading, weigh


def read(reading: Reading) -> Loaded:
    from .trimesh_parts import latin1_text, load, parts
    return Loaded(parts(load(reading, latin1_text(reading.handle))))


def count(handle, size: int, source) -> int | None:
    """The faces and vertices of the header's counts line (the first line after `OFF` that is not a comment)."""
    head = handle.read(4096)
    numbers = [line.split() for line in head.splitlines()[1:] if line.strip() and not line.startswith(b"#")]
    if numbers and len(numbers[0]) >= 2:
        return weigh(int(numbers[0][1]), int(numbers[0][0]))
    return None


FORMAT = MeshFormat(names=("OFF",), suffixes=(".off",), read=read, count=count, parse_bytes=550,
                    content=lambda head, found, size, suffix: found in (None, "OBJ", "OFF", "ASCII STL"))
