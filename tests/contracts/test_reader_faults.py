"""Hostile files each reader met in an audit (issue 50): every one is exit 2 and one line naming the file, or a
render, and never an internal error, a traceback or a library's own line on stderr. Each runs as a process, as a
user runs it, because the native libraries print to the process's stderr (fd 2), not to Python's."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp

CORE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
LIGHT = '[[lights]]\ntype = "point"\nposition = [3, 4, 6]\n'


def model_xml(vertices: list[tuple]) -> str:
    points = "".join(f'<vertex x="{x}" y="{y}" z="{z}"/>' for x, y, z in vertices)
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" xmlns="{CORE}"><resources>'
            f'<object id="1" type="model"><mesh><vertices>{points}</vertices><triangles><triangle v1="0" v2="1" '
            'v3="2"/></triangles></mesh></object></resources><build><item objectid="1"/></build></model>')


TRIANGLE = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]


def three_mf(path: Path, model: str, compress: int = zipfile.ZIP_DEFLATED, flags: int = 0) -> Path:
    """A 3MF of one model part; `compress` and `flags` are written into its local and central headers as given
    (a method zipfile cannot read, the encrypted bit), the data left as deflate wrote it."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("3D/3dmodel.model", model)
    data = bytearray(path.read_bytes())
    for signature, at in ((b"PK\x03\x04", 6), (b"PK\x01\x02", 8)):  # local header, central directory entry
        start = data.find(signature)
        struct.pack_into("<HH", data, start + at, flags | struct.unpack_from("<H", data, start + at)[0], compress)
    path.write_bytes(bytes(data))
    return path


def gltf(path: Path, primitives: list, uv: np.ndarray | None = None) -> Path:
    """A .gltf of one triangle (positions, texture coordinates `uv`, indices) in a data: URI buffer."""
    import base64
    points = np.array(TRIANGLE, "<f4")
    uv = np.zeros((3, 2), "<f4") if uv is None else uv.astype("<f4")
    data = points.tobytes() + uv.tobytes() + np.array([0, 1, 2], "<u2").tobytes()
    tree = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": primitives}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0],
                           "max": [1, 1, 0]},
                          {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"},
                          {"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"}],
            "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                            {"buffer": 0, "byteOffset": 36, "byteLength": 24},
                            {"buffer": 0, "byteOffset": 60, "byteLength": 6}],
            "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}}],
            "buffers": [{"byteLength": len(data),
                         "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}]}
    path.write_text(json.dumps(tree))
    return path


def truncated_png(path: Path) -> Path:
    """A PNG cut inside its IHDR chunk."""
    header = struct.pack(">IIBBBBB", 64, 64, 8, 2, 0, 0, 0)
    chunk = struct.pack(">I", len(header)) + b"IHDR" + header + struct.pack(">I", zlib.crc32(b"IHDR" + header))
    path.write_bytes((b"\x89PNG\r\n\x1a\n" + chunk)[:20])
    return path


def textured_scene(path: Path, map_name: str) -> Path:
    path.write_text(f'[render]\nwidth = 32\nheight = 24\n\n[materials.m]\nkd_map = {json.dumps(map_name)}\n\n'
                    f'[[objects]]\nshape = "uv_sphere"\nmaterial = "m"\n\n{LIGHT}')
    return path


def mesh_scene(path: Path, mesh_name: str) -> Path:
    path.write_text(f'[[objects]]\nshape = "mesh"\npath = {json.dumps(mesh_name)}\n\n{LIGHT}')
    return path


def run(*arguments: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "raycast_phong.cli", *arguments], cwd=cwd, capture_output=True,
                          text=True, timeout=180)


def nested_boxes(path: Path, levels: int) -> Path:
    """A 3MF whose object k + 1 holds ten components of object k, `levels` deep: 10^levels triangles."""
    objects = ('<object id="1" type="model"><mesh><vertices><vertex x="0" y="0" z="0"/><vertex x="1" y="0" z="0"/>'
               '<vertex x="0" y="1" z="0"/></vertices><triangles><triangle v1="0" v2="1" v3="2"/></triangles></mesh>'
               '</object>')
    for k in range(2, levels + 2):
        objects += (f'<object id="{k}" type="model"><components>'
                    + f'<component objectid="{k - 1}"/>' * 10 + '</components></object>')
    model = (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" xmlns="{CORE}"><resources>{objects}'
             f'</resources><build><item objectid="{levels + 1}"/></build></model>')
    return three_mf(path, model)


REFUSED = {  # case: (make the input in a folder → the file to render, words the line must hold)
    "3MF with an encrypted part": (lambda d: three_mf(d / "e.3mf", model_xml(TRIANGLE), flags=1),
                                   "is encrypted, password required"),
    "3MF with an unknown compression": (lambda d: three_mf(d / "c.3mf", model_xml(TRIANGLE), compress=99),
                                        "compression method is not supported"),
    "3MF coordinate 'abc'": (lambda d: three_mf(d / "a.3mf", model_xml([("abc", 0, 0), *TRIANGLE[1:]])),
                             "a vertex coordinate that is not a number"),
    "3MF infinite vertex": (lambda d: three_mf(d / "i.3mf", model_xml([("1e999", 0, 0), *TRIANGLE[1:]])),
                            "NaN or infinite coordinates"),
    "glTF primitive that is a number": (lambda d: gltf(d / "p.gltf", [5]), "cannot read the file as glTF"),
    "kd_map with a NUL byte": (lambda d: textured_scene(d / "s.toml", "tex\0.png"), "no such texture file"),
    "mesh path with a NUL byte": (lambda d: mesh_scene(d / "s.toml", "m\0.obj"), "no such mesh file 'm\\x00.obj'"),
    "truncated PNG map": (lambda d: textured_scene(d / "s.toml", truncated_png(d / "cut.png").name),
                          "cannot be read as an image"),
}


@pytest.mark.parametrize("case", REFUSED)
def test_a_hostile_file_is_one_line_and_exit_2(case, tmp_path):
    make, words = REFUSED[case]
    given = make(tmp_path)
    done = run("render", given.name, "-o", "out.png", cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and done.stderr.startswith(f"error: {given.name}: "), done.stderr
    assert words in done.stderr, done.stderr
    assert not (tmp_path / "out.png").exists()


def test_a_3mf_of_nested_components_is_refused_from_what_it_builds(tmp_path):
    """A 2 kB file of 10^6 triangles (ten components a level, six levels) passed the memory check, which weighed
    the parsed file: it grew past 3.5 GB at 10^8. Its count is now what it builds."""
    nested_boxes(tmp_path / "n.3mf", 6)
    done = run("render", "n.3mf", "-o", "out.png", "--max-memory", "300M", cwd=tmp_path)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "reading its 1.0M triangles needs" in done.stderr, done.stderr


def glb_with_image(path: Path, image: bytes) -> Path:
    """A .glb of one textured triangle whose base colour map is `image`, stored in its binary chunk."""
    points, uv = np.array(TRIANGLE, "<f4").tobytes(), np.zeros((3, 2), "<f4").tobytes()
    indices = np.array([0, 1, 2, 0], "<u2").tobytes()
    data = points + uv + indices + image + bytes(-len(image) % 4)
    views = [(0, 36), (36, 24), (60, 6), (68, len(image))]
    tree = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2,
                                        "material": 0}]}],
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0}], "images": [{"bufferView": 3, "mimeType": "image/png"}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0],
                           "max": [1, 1, 0]},
                          {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"},
                          {"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"}],
            "bufferViews": [{"buffer": 0, "byteOffset": at, "byteLength": length} for at, length in views],
            "buffers": [{"byteLength": len(data)}]}
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(data), 0x004E4942) + data
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(chunks)) + chunks)
    return path


def test_an_embedded_map_is_weighed_at_the_size_it_is_decoded_whole(tmp_path):
    """A 12000² PNG in a .glb's buffer (between PIL's warning and error sizes) was decoded whole, 999 MB under a
    300 MB budget, with PIL's DecompressionBombWarning on stderr: its header's texels are now the read's."""
    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    header = struct.pack(">IIBBBBB", 12000, 12000, 8, 2, 0, 0, 0)  # its header is what is weighed
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(bytes(1000))) + \
        chunk(b"IEND", b"")
    glb_with_image(tmp_path / "big.glb", png)
    done = run("render", "big.glb", "-o", "out.png", "--max-memory", "300M", cwd=tmp_path)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "needs ≈ 1.07 GB of memory, more than the 300 MB available" in done.stderr, done.stderr


def test_nan_texture_coordinates_render_without_numpy_s_warning(tmp_path):
    """NaN UVs are read as 0 by the kernel (they rendered before a check's nanmax warned 'All-NaN slice')."""
    primitives = [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]
    gltf(tmp_path / "n.gltf", primitives, uv=np.full((3, 2), np.nan))
    done = run("render", "n.gltf", "-o", "out.png", "-q", cwd=tmp_path)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert (tmp_path / "out.png").is_file()


def test_nan_texture_coordinates_of_an_obj_render_as_a_gltf_s_do(tmp_path):
    """`vt nan nan` renders, as NaN UVs of a glTF do: it was refused as 'a texture coordinate beyond float32's
    range', with no line named, by a check that took NaN for out of range."""
    (tmp_path / "n.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt nan nan\nvt 0 0\nvt 1 0\nf 1/1 2/2 3/3\n")
    done = run("render", "n.obj", "-o", "out.png", "-q", cwd=tmp_path)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert (tmp_path / "out.png").is_file()


def test_a_400_digit_memory_budget_is_one_line(tmp_path):
    done = run("render", "-o", "out.png", "--max-memory", "9" * 400, cwd=tmp_path)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "--max-memory" in done.stderr and "more characters" in done.stderr, done.stderr


def textured_gltf(path: Path, image: str) -> Path:
    """gltf() of one triangle whose base colour map is the image file `image` beside it."""
    tree = json.loads(gltf(path, [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}],
                           uv=np.array([[0.1, 0.1], [0.9, 0.1], [0.1, 0.9]])).read_text())
    tree["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    tree |= {"textures": [{"source": 0}], "images": [{"uri": image}]}
    path.write_text(json.dumps(tree))
    return path


def test_a_gltf_s_image_file_past_the_decoded_size_is_shrunk_as_read_not_opened_whole(tmp_path, monkeypatch):
    """A glTF's external image larger than MAX_TEXTURE_SIZE is given to the decode as its file, which shrinks it
    a band of rows at a time (as the memory estimate counts it), not opened by PIL, which decodes it whole first
    (a 12000² PNG: 962 MB peak under --max-memory 300M) or, past its bomb limit, refused it: the map was then
    silently left out. PIL's limit is lowered here so that a 3000² map stands for the 20000² one."""
    import PIL.Image

    from raycast_phong.io.meshes import read as mesh_file
    from raycast_phong.io.meshes.source import mesh_source
    from raycast_phong.io.textures import MAX_TEXTURE_SIZE, decode_file
    rp.write_image(tmp_path / "big.png", np.full((3000, 3000, 3), 0.5, np.float32))
    rp.write_image(tmp_path / "small.png", np.full((64, 64, 3), 0.5, np.float32))
    monkeypatch.setattr(PIL.Image, "MAX_IMAGE_PIXELS", 3_000_000)  # 3000² is past twice this: PIL's error
    for name, kind in (("big.png", Path), ("small.png", PIL.Image.Image)):
        read = mesh_file.read_file(mesh_source(textured_gltf(tmp_path / f"{name}.gltf", name)))
        [source] = read.texture_sources
        assert isinstance(source.source, kind), (name, source)
    assert decode_file(tmp_path / "big.png", "display").shape == (MAX_TEXTURE_SIZE, MAX_TEXTURE_SIZE, 3)
