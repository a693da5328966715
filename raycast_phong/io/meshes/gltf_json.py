"""A glTF's JSON document (a .gltf, or a .glb's first chunk), parsed once per file (its MeshSource keeps it), and
the files its URIs name: buffers and images beside it. No trimesh."""

from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple
from urllib.parse import unquote

from ...errors import SceneError
from ..files import open_regular

JSON_LIMIT = 64 << 20  # a glTF's JSON above this is not parsed here (the size bound weighs it; trimesh reads it)
MESHOPT = ("EXT_meshopt_compression", "KHR_meshopt_compression")  # the two names of meshopt compression
# glTF 1.0 (shader techniques for materials, KHR_binary_glTF for its .glb) is not read: it says what converts it.
OLD = " (glTF 1.0, read here only once converted, e.g. by Blender's importer or gltf-pipeline)"
ALLOWED_VERSION = "glTF 2.0 (asset.version 2.x, a GLB of version 2)"


class Document(NamedTuple):
    """A glTF's JSON as read: the parsed document ({} when it is not JSON or too large to parse here),
    where a .glb's binary chunk lies (offset, length; None for a .gltf or a .glb without one), and a problem
    the read must refuse with (a JSON nested deeper than Python parses), else None."""
    tree: dict
    binary: tuple[int, int] | None
    problem: str | None


def read_document(path: Path) -> Document:
    """The JSON of the glTF at `path` (a .glb's first chunk), at most JSON_LIMIT bytes of it; reading stops
    there (a .glb's binary chunk is not read). A missing or unreadable file gives an empty document (the
    read words the error)."""
    binary = None
    try:
        with open_regular(path, str(path), "mesh file") as handle:
            if path.suffix.lower() == ".glb":
                header = handle.read(20)
                length = int.from_bytes(header[12:16], "little")
                container = int.from_bytes(header[4:8], "little")
                if header[:4] == b"glTF" and len(header) >= 8 and container != 2:
                    return Document({}, None, f"its GLB header gives version {container}"
                                              f"{OLD if container == 1 else ''}; allowed: {ALLOWED_VERSION}")
                if header[:4] != b"glTF" or header[16:20] != b"JSON" or length > JSON_LIMIT:
                    return Document({}, None, None)
                text = handle.read(length)
                chunk = handle.read(8)
                if len(text) == length and chunk[4:8] == b"BIN\x00":
                    binary = (20 + length + 8, int.from_bytes(chunk[:4], "little"))
            else:
                text = handle.read(JSON_LIMIT + 1)
                if len(text) > JSON_LIMIT:
                    return Document({}, None, None)
        tree = json.loads(text)
    except json.JSONDecodeError as error:  # trimesh read it otherwise, and named a file it then looked for
        return Document({}, None, f"its JSON does not parse (line {error.lineno}, column {error.colno}: "
                                  f"{error.msg}); allowed: a glTF 2.0 document in JSON")
    except UnicodeDecodeError:
        return Document({}, None, "its JSON is not UTF-8 text; allowed: a glTF 2.0 document in UTF-8 JSON")
    except (OSError, SceneError, ValueError):
        return Document({}, None, None)  # trimesh words what is wrong with the file
    except RecursionError:  # Python's parser recurses per level: no glTF is nested a thousand deep
        return Document({}, None, "its JSON is nested deeper than Python's parser reads; allowed: a glTF document "
                                  "(a few levels of objects and lists)")
    tree = tree if isinstance(tree, dict) else {}
    return Document(tree, binary, _version_problem(tree))


def _version_problem(tree: dict) -> str | None:
    """A document whose asset.version has a major number other than 2 (glTF 2.0 §5.2: a loader reads only the
    major version it knows; a later minor one is read). A missing or malformed version is left to the read."""
    asset = tree.get("asset")
    version = asset.get("version") if isinstance(asset, dict) else None
    major = version.split(".")[0] if isinstance(version, str) else ""
    if not major.isdigit() or int(major) == 2:
        return None
    return f"its asset.version is {version[:20]!r}{OLD if int(major) == 1 else ''}; allowed: {ALLOWED_VERSION}"


def uri_file(folder: Path, uri: str) -> Path:
    """The file a glTF's relative URI names: percent-decoded (glTF 2.0 §3.3.3: URIs are RFC 3986, so a space
    is written %20), unless a file of the name as written exists (exporters that write spaces as they are)."""
    written = folder / uri
    return written if "%" not in uri or written.is_file() else folder / unquote(uri)


def file_uris(document: dict, table: str) -> list[str]:
    """The files outside the glTF that its `table` ("buffers", "images") names: its URIs other than data:, as
    written (uri_file finds the file); none for a table that is not a list (the read reports it)."""
    try:
        return [row["uri"] for row in document.get(table, []) if isinstance(row, dict)
                and isinstance(row.get("uri"), str) and not row["uri"].startswith("data:")]
    except (TypeError, AttributeError):
        return []
