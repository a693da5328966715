"""A mesh file's size before it is read: its triangle count from the header (PLY, OFF, binary STL, glTF) or
a cheap scan in bounded pieces (OBJ's face corners), the least its read costs from its size and format,
and whether reading it could fit in memory at all.

Counts are kept per file version (io.files.VersionCache): framing's check and the render's estimate both ask.
A glTF is counted from the document its io/mesh_source.MeshSource parsed, when the caller has one. No trimesh.
"""

from __future__ import annotations

import json
import os
import re
import struct
from pathlib import Path

import numpy as np

from ..errors import SceneError, Where
from .files import VersionCache, file_version, open_regular
from .gltf import JSON_LIMIT, Document, gltf_buffer_files
from .system import count_text, format_bytes, memory_allowed

# trimesh's load of a mesh file, above the render's own peak (the parse of a text file is larger). A binary STL
# is read by io/mesh_file.py itself as float32 corners (its 50-byte records, then 36 + 24 bytes a triangle of
# points and faces, below the render's peak: bunny-1m phong 279 B/triangle against the PLY's 287, flat 215
# against 270, 8×8, one thread); an ASCII STL, parsed by trimesh, is bounded by its size (mesh_file_read_bytes).
MESH_FILE_BYTES = {".ply": 30, ".obj": 80, ".glb": 70, ".gltf": 70, ".stl": 30, ".off": 550}
OTHER_MESH_FILE_BYTES = 550
# Bytes per triangle of reading a mesh file and holding it for a flat render: renderer.budget.FLAT_BYTES, the
# measured figure (a test keeps the two equal; here so framing, below the renderer, can check a read).
MESH_READ_BYTES = 270


def mesh_file_triangles(path: Path, where: Where, document: Document | None = None) -> int:
    """Triangles in a mesh file, read cheaply: PLY and OFF headers, binary STL's count, OBJ's face corners,
    glTF's accessor counts (a JSON above JSON_LIMIT is not parsed); other formats by file size (at least 6
    bytes per triangle). Where the file's vertices outnumber its triangles, its vertices (less 2):
    unused vertices cost memory too. 0 for a missing file (the loader reports it); a FIFO, device or folder is
    refused here, and so is a binary STL whose size does not match its header's count (SceneError). `document`:
    a glTF's, already parsed (MeshSource.document), so it is not parsed again."""
    try:
        handle = open_regular(path, where, "mesh file")
    except FileNotFoundError:
        return 0
    with handle:
        info = os.fstat(handle.fileno())
        # An OBJ is counted in 1 MB pieces: once per version; framing and the render ask.
        suffix = path.suffix.lower()
        return COUNTS.setdefault(file_version(path, info),
                                 lambda: _count_triangles(handle, suffix, info.st_size, where, document))


def mesh_file_read_bytes(path: Path, buffers: tuple[Path, ...] | None = None) -> int:
    """The least memory reading a mesh file costs, from its size and format alone (0 if it is not there):
    the floor under the triangle count's estimate for a file that claims little and is large. `buffers`: a
    .gltf's external buffer files (MeshSource.side_files), else read from its JSON."""
    try:
        size = path.stat().st_size
    except OSError:
        return 0
    suffix = path.suffix.lower()
    if suffix == ".stl" and _binary_stl(path, size):
        return size * BINARY_STL_READ_BYTES_PER_BYTE
    external, unzipped = _held_bytes(path, buffers)
    if suffix == ".3mf":
        return size + unzipped * ZIP_XML_READ_BYTES_PER_BYTE
    return size * READ_BYTES_PER_BYTE.get(suffix, TEXT_READ_BYTES_PER_BYTE) + external * BUFFER_READ_BYTES_PER_BYTE


def _held_bytes(path: Path, buffers: tuple[Path, ...] | None = None) -> tuple[int, int]:
    """What a read of the file decodes besides its own bytes: (a .gltf's external buffers, read whole whatever its
    accessors claim to use of them; a 3MF's members unzipped: an 800 MB XML zips to 2 MB). `buffers`: the
    .gltf's buffer files if known, else read from its JSON."""
    suffix = path.suffix.lower()
    if suffix == ".gltf":
        return sum(_size(buffer) for buffer in (gltf_buffer_files(path) if buffers is None else buffers)), 0
    if suffix == ".3mf":
        return 0, _zip_content_bytes(path)
    return 0, 0


def _zip_content_bytes(path: Path) -> int:
    """The sum of the sizes a zip's directory gives its members, uncompressed. Python's zipfile (trimesh's 3MF
    reader uses it) stops a member at its stated size (a longer stream fails its check), so the sum bounds what a
    read decompresses. 0 for a file that is not a zip (the loader reports it)."""
    import zipfile
    try:
        with open_regular(path, str(path), "mesh file") as handle, zipfile.ZipFile(handle) as archive:
            return sum(info.file_size for info in archive.infolist())
    except (OSError, SceneError, zipfile.BadZipFile, ValueError, EOFError):
        return 0


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return 0  # the loader reports a missing buffer


def _binary_stl(path: Path, size: int) -> bool:
    """Whether the STL at `path` is binary: its size is 84 + 50 × the count its header gives."""
    try:
        with open_regular(path, str(path), "mesh file") as handle:
            head = handle.read(84)
    except (OSError, SceneError):
        return False
    return len(head) == 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little")


COUNTS: VersionCache[int] = VersionCache(64)  # file version → triangles

# A file is read whole and parsed before any triangle exists: trimesh holds the text, its decoded str and its
# split tokens. Measured (trimesh 4, peak RSS over the interpreter's): an icosphere-7 OBJ of 12.8 MB 93 MB;
# a 100 MB OBJ of vertex lines 1.0 GB, of one line 1.9 GB, of face lines 2.0 GB. So reading a file costs at
# least its size times these bytes, whatever its header claims (the counts above cover the face lines).
READ_BYTES_PER_BYTE = {".glb": 2}  # binary chunks are read as they are
TEXT_READ_BYTES_PER_BYTE = 12      # a text file, or one that may be (PLY, an ASCII STL)
# A binary STL's records (its size) and the points and faces copied out of them (72% and 48% of it).
BINARY_STL_READ_BYTES_PER_BYTE = 3
# A .gltf's external buffer is read whole into bytes (trimesh's resolver): a 600 MB buffer of which the accessors
# use 36 bytes peaked 734 MB (interpreter included).
BUFFER_READ_BYTES_PER_BYTE = 1
# A 3MF's XML, parsed by trimesh into a tree and lists: a 178 kB 3MF of 56.5 MB XML (500k triangles) peaked
# 1.95 GB resident, 34.5 bytes a byte of XML.
ZIP_XML_READ_BYTES_PER_BYTE = 36
CHUNK = 1 << 20  # an OBJ is scanned this many bytes at a time (about 20 MB of index arrays), never a whole line


def _count_triangles(handle, suffix: str, size: int, where: Where = "mesh file",
                     document: Document | None = None) -> int:
    """Triangles' worth of the open file `handle` of `size` bytes (mesh_file_triangles, before the size bound)."""
    head = handle.read(4096)
    try:
        if suffix == ".ply":
            faces = re.search(rb"^element\s+face\s+(\d+)", head, re.M)
            points = re.search(rb"^element\s+vertex\s+(\d+)", head, re.M)
            listed = _ply_list_triangles(head, size)
            if faces or listed is not None:
                return _weigh(max(int(faces[1]) if faces else 0, listed or 0), int(points[1]) if points else 0)
        elif suffix == ".stl":
            binary = size >= 84 and (not head.lstrip().startswith(b"solid")
                                     or size == 84 + 50 * struct.unpack_from("<I", head, 80)[0])
            if binary:
                count = struct.unpack_from("<I", head, 80)[0]
                if size != 84 + 50 * count:
                    raise SceneError(f"a binary STL whose header counts {count:,} triangles "
                                     f"({84 + 50 * count:,} bytes) but which has {size:,} bytes: the file is "
                                     "corrupt or cut short; allowed: 84 + 50 × its count bytes", where)
                return count
            return size // 86  # the shortest ASCII facet ("facet normal 0 0 0\nouter loop\n…") is 86 bytes
        elif suffix == ".off":
            numbers = [line.split() for line in head.splitlines()[1:] if line.strip() and not line.startswith(b"#")]
            if numbers and len(numbers[0]) >= 2:
                return _weigh(int(numbers[0][1]), int(numbers[0][0]))
        elif suffix == ".obj":
            handle.seek(0)
            return _obj_triangles(handle)
        elif suffix in (".glb", ".gltf") and document is not None:
            if document.tree:
                return _gltf_triangles(document.tree)
        elif suffix == ".glb" and head[:4] == b"glTF":
            length = struct.unpack_from("<I", head, 12)[0]
            if length <= JSON_LIMIT:
                handle.seek(20)
                return _gltf_triangles(json.loads(handle.read(length)))
        elif suffix == ".gltf" and size <= JSON_LIMIT:
            handle.seek(0)
            return _gltf_triangles(json.loads(handle.read()))
    except SceneError:
        raise
    except (ValueError, KeyError, IndexError, TypeError, struct.error, OSError, RecursionError):
        pass  # a malformed header: fall back to the size bound; the loader reports the real problem
    return size // 6


PLY_SIZES = {"char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2, "uint16": 2,
             "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


def _ply_list_triangles(head: bytes, size: int) -> int | None:
    """The most triangles a binary PLY's lists (faces, strips) can make, from its size and its header's
    types, whatever its counts claim: the bytes past the fixed-size properties hold at most that many list
    entries of the smallest index type, and n entries of a polygon or strip make n − 2 triangles. Exact for
    a file of triangles (a face of 3 M corners, header "1 face", is 3 M triangles). None for an ASCII PLY, a
    header longer than `head`, or no list."""
    end = head.find(b"end_header")
    if end < 0 or head.find(b"\n", end) < 0 or re.search(rb"^format\s+ascii", head[:end], re.M):
        return None
    body = size - head.index(b"\n", end) - 1
    elements = []  # [count, bytes of its fixed properties and list counts, smallest list entry or 0]
    for words in (line.split() for line in head[:end].decode("ascii", "replace").splitlines()):
        if words[:1] == ["element"] and len(words) == 3:
            elements.append([int(words[2]), 0, 0])
        elif words[:1] == ["property"] and elements and len(words) in (3, 5):
            if words[1] == "list" and len(words) == 5:
                entry = PLY_SIZES[words[3]]
                elements[-1][1] += PLY_SIZES[words[2]]
                elements[-1][2] = min(elements[-1][2] or entry, entry)
            else:
                elements[-1][1] += PLY_SIZES[words[1]]
    lists = [(count, entry) for count, _, entry in elements if entry]
    if not lists:
        return None
    entries = max(0, body - sum(count * fixed for count, fixed, _ in elements)) // min(e for _, e in lists)
    return max(0, entries - 2 * sum(count for count, _ in lists))


def _weigh(triangles: int, vertices: int) -> int:
    """Triangles, or the vertices less 2 where those are more: a closed surface has T/2 + 2 vertices and an
    open one a few more, so only vertices far beyond what the faces need (millions unused) raise the count.
    A vertex read costs about 130 bytes (7.5M vertex lines of OBJ: 1.0 GB), a triangle's worth more."""
    return max(triangles, vertices - 2)


def _obj_triangles(handle) -> int:
    """An OBJ's triangles (a face of k corners is k − 2), or its vertices where more (_weigh), scanned in
    CHUNK-byte pieces with numpy: a line is never held whole, so a one-line 1 GB file costs about 20 MB here.

    Each piece is seen with the stream's two bytes before it, so a line that starts at a piece's edge is
    classified (its first two bytes: `f ` or `v `) exactly once, and a token start (a non-blank byte after a
    blank one) is counted in the line it belongs to."""
    triangles = vertices = open_tokens = 0
    before, in_face = b"\n\n", False
    while True:
        chunk = handle.read(CHUNK)
        buffer = np.frombuffer(before + (chunk or b"\n"), np.uint8)
        # Positions 1 .. len − 2 of the buffer are this piece's (each stream byte once over the pieces).
        starts = np.flatnonzero(buffer[:-2] == 10) + 1
        blank = buffer <= 32
        first, second = buffer[starts], buffer[starts + 1]
        gap = (second == 32) | (second == 9)
        face = np.concatenate(([in_face], (first == ord("f")) & gap))  # 0: the line carried from before
        vertices += int(np.count_nonzero((first == ord("v")) & gap))
        begins = np.flatnonzero(~blank[1:-1] & blank[:-2]) + 1
        line = np.searchsorted(starts, begins, side="right")
        tokens = np.bincount(line[face[line]], minlength=len(face))  # per line: `f` and its corners
        tokens[0] += open_tokens
        closed = tokens if not chunk else tokens[:-1]  # the last line may go on in the next piece
        triangles += int(np.maximum(closed - 3, 0).sum())
        if not chunk:
            break
        open_tokens, in_face = int(tokens[-1]), bool(face[-1])
        before = buffer[-2:].tobytes()
    return _weigh(triangles, vertices)


def _gltf_triangles(document: dict) -> int:
    """Triangles over every node's mesh (each node counts, and each instance of an EXT_mesh_gpu_instancing node:
    instances × the mesh's triangles), from the accessors' counts; or their vertices (less 2) where more (_weigh:
    a compressed bufferView decodes to what its accessors read, io/gltf_decode.py)."""
    accessors, meshes = document.get("accessors", []), document.get("meshes", [])
    placed = [node for node in document.get("nodes", []) if "mesh" in node]
    uses = [(node["mesh"], _instances(node, accessors)) for node in placed] or [(m, 1) for m in range(len(meshes))]
    total = vertices = 0
    for mesh, copies in uses:
        for primitive in meshes[mesh].get("primitives", []):
            indexed = primitive.get("indices", primitive.get("attributes", {}).get("POSITION"))
            total += copies * (accessors[indexed]["count"] // 3)
            vertices += copies * int(accessors[primitive.get("attributes", {}).get("POSITION", indexed)]["count"])
    return _weigh(total, vertices)


def _instances(node: dict, accessors: list) -> int:
    """How many times a node places its mesh: its EXT_mesh_gpu_instancing accessors' count (the largest, if they
    disagree: the read refuses that), else 1."""
    extensions = node.get("extensions")
    found = extensions.get("EXT_mesh_gpu_instancing") if isinstance(extensions, dict) else None
    attributes = found.get("attributes") if isinstance(found, dict) else None
    if not isinstance(attributes, dict):
        return 1  # not instanced, or malformed: the read words it
    return max((int(accessors[index]["count"]) for index in attributes.values()), default=1)


def check_mesh_read(path: Path, where: Where, max_memory: int | None = None, mesh=None) -> None:
    """Refuse (SceneError, one line) to read a mesh file for framing (scene.framing, before any render and
    so before renderer.budget.check_memory) when the read alone could not fit in the memory available now
    (io.system.available_memory: cgroup and `ulimit -v`; and `max_memory`, the command's --max-memory): the
    file's size × its parse (mesh_file_read_bytes, checked first, so a huge file is never scanned), or its
    triangles (from the header, mesh_file_triangles) × the flat render's bytes per triangle and the format's
    parse. `mesh`: the file's io.mesh_source.MeshSource (its glTF document and buffer files), if made."""
    buffers = mesh.side_files if mesh is not None and path.suffix.lower() == ".gltf" else None
    document = mesh.document if mesh is not None else None
    available = memory_allowed(max_memory)
    floor = mesh_file_read_bytes(path, buffers)  # from the size alone: a huge file is refused before any byte is read
    triangles = 0 if available is not None and floor > available else mesh_file_triangles(path, where, document)
    need = max(triangles * (MESH_READ_BYTES + MESH_FILE_BYTES.get(path.suffix.lower(), OTHER_MESH_FILE_BYTES)),
               floor)
    if available is not None and need > available:
        external, unzipped = _held_bytes(path, buffers)  # said only when refused
        what = (f"{count_text(triangles)} triangles" if triangles else f"{format_bytes(path.stat().st_size)}"
                + (f" and {format_bytes(external)} of buffers" if external else "")
                + (f" ({format_bytes(unzipped)} unzipped)" if unzipped else ""))
        raise SceneError(f"reading its {what} needs ≈ {format_bytes(need)} of memory, more than the "
                         f"{format_bytes(available)} available; allowed: a mesh whose size and triangles fit, "
                         "so decimate it or free memory", where)
