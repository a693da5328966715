"""Guards on what a file costs to read, not what it claims (issue 21, item 1): a large mesh file that claims
few triangles (one line, zeros, a sparse file) is refused from its size and format before it is read; a
binary STL whose size does not match its count is corrupt; an OBJ is counted in bounded pieces; unused
vertices count; the budget follows `ulimit -v`.
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.io.meshes import obj as obj_format
from raycast_phong.io.meshes.source import mesh_source

CLI = [sys.executable, str(Path(__file__).parents[2] / "cli.py")]


def sparse(path: Path, size: int, head: bytes = b"") -> Path:
    """A file of `size` bytes that takes no disk: `head`, then a hole (zeros)."""
    with open(path, "wb") as handle:
        handle.write(head)
        handle.truncate(size)
    return path


def run_measured(args: list[str], cwd: Path) -> tuple[subprocess.CompletedProcess, int, float]:
    """The CLI in a fresh process: its result, its peak resident bytes (through a wrapper that reads its own
    children's ru_maxrss) and its wall time."""
    probe = ("import resource, subprocess, sys; done = subprocess.run(sys.argv[1:], capture_output=True, "
             "text=True, stdin=subprocess.DEVNULL); sys.stderr.write(done.stderr); sys.stdout.write(done.stdout); "
             "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
             "sys.exit(done.returncode)")
    env = {k: v for k, v in os.environ.items() if k != "RAYCAST_PHONG_DEBUG"}
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", probe, *CLI, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env=env)
    seconds = time.perf_counter() - started
    lines = done.stderr.strip().splitlines()
    peak = int(lines[-1]) * 1024
    done.stderr = "\n".join(lines[:-1])
    return done, peak, seconds


@pytest.mark.parametrize("name, head", [("one-line.obj", b"v 0 0 0 "), ("zeros.stl", b""),
                                        ("huge.gltf", b'{"asset": {"version": "2.0"}, "x": "'),
                                        ("zeros.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
                                                      b"property float x\nproperty float y\nproperty float z\n"
                                                      b"element face 1\nproperty list uchar int vertex_indices\n"
                                                      b"end_header\n")])
def test_a_large_file_claiming_little_is_refused_before_it_is_read(tmp_path, name, head):
    """512 MB that claim nothing, --max-memory 100M: one line, exit 2, in seconds, without reading the file
    (before the change: the whole file was read by the count and by trimesh, gigabytes)."""
    path = sparse(tmp_path / name, 512 << 20, head)
    done, peak, seconds = run_measured(["render", str(path), "--max-memory", "100M", "-o",
                                        str(tmp_path / "out.png")], tmp_path)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert name in lines[0] and ("memory" in lines[0] or "corrupt" in lines[0]), lines[0]
    assert peak < 400 << 20, f"{peak >> 20} MB resident to refuse {name}"
    assert seconds < 60


def test_a_gltf_whose_accessors_use_little_of_a_large_buffer_is_refused_before_it_is_read(tmp_path):
    """Issue 30 item 3: a .gltf whose accessors claim one triangle of a 512 MB external buffer, --max-memory
    100M: the buffer is read whole (trimesh's resolver), so its size counts; one line naming the buffers, exit 2,
    the buffer unread (before: 734 MB resident for a 600 MB buffer, exit 0)."""
    import json
    import struct
    sparse(tmp_path / "big.bin", 512 << 20, struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0))
    path = tmp_path / "lie.gltf"
    path.write_text(json.dumps({
        "asset": {"version": "2.0"}, "buffers": [{"uri": "big.bin", "byteLength": 512 << 20}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "nodes": [{"mesh": 0}]}))
    done, peak, _ = run_measured(["render", str(path), "--max-memory", "100M", "-o", str(tmp_path / "o.png")],
                                 tmp_path)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert lines[0].startswith(f"error: {path}: ") and "512 MB of buffers" in lines[0], lines[0]
    assert peak < 400 << 20, f"{peak >> 20} MB resident to refuse it"
    assert not (tmp_path / "o.png").exists()


def three_mf(path: Path, copies: int) -> Path:
    """A 3MF (a zip of XML) of one triangle's three vertices and one triangle, each written `copies` times."""
    import zipfile
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("[Content_Types].xml", '<?xml version="1.0" encoding="UTF-8"?><Types xmlns="http://schemas'
                         '.openxmlformats.org/package/2006/content-types"><Default Extension="rels" ContentType="appl'
                         'ication/vnd.openxmlformats-package.relationships+xml"/><Default Extension="model" ContentT'
                         'ype="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/></Types>')
        archive.writestr("_rels/.rels", '<?xml version="1.0" encoding="UTF-8"?><Relationships xmlns="http://schemas.'
                         'openxmlformats.org/package/2006/relationships"><Relationship Target="/3D/3dmodel.model" '
                         'Id="rel0" Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>'
                         '</Relationships>')
        with archive.open("3D/3dmodel.model", "w") as model:
            model.write(b'<?xml version="1.0" encoding="UTF-8"?><model unit="millimeter" xmlns="http://schemas.'
                        b'microsoft.com/3dmanufacturing/core/2015/02"><resources><object id="1" type="model"><mesh>'
                        b'<vertices>')
            model.write(b'<vertex x="0" y="0" z="0"/><vertex x="1" y="0" z="0"/><vertex x="0" y="1" z="0"/>' * copies)
            model.write(b'</vertices><triangles>' + b'<triangle v1="0" v2="1" v3="2"/>' * copies)
            model.write(b'</triangles></mesh></object></resources><build><item objectid="1"/></build></model>')
    return path


def test_a_3mf_is_weighed_by_what_it_unzips_to(tmp_path):
    """Issue 30 item 3: a 3MF whose 17 MB of XML zip to 60 kB, --max-memory 100M: refused from its zip
    directory's sizes before any XML is parsed (one line, exit 2); before, its size alone counted and trimesh
    parsed it (a 178 kB 3MF of 56.5 MB XML peaked 1.95 GB under --max-memory 300M). A small 3MF still renders."""
    bomb = three_mf(tmp_path / "bomb.3mf", 150_000)
    assert bomb.stat().st_size < 1 << 20
    done, peak, _ = run_measured(["render", str(bomb), "--max-memory", "100M", "-o", str(tmp_path / "o.png")],
                                 tmp_path)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert lines[0].startswith(f"error: {bomb}: ") and "unzipped" in lines[0] and "memory" in lines[0], lines[0]
    assert peak < 400 << 20, f"{peak >> 20} MB resident to refuse it"
    small = three_mf(tmp_path / "small.3mf", 1)
    done, _, _ = run_measured(["render", str(small), "--max-memory", "100M", "-o", str(tmp_path / "s.png")], tmp_path)
    assert done.returncode == 0 and (tmp_path / "s.png").exists(), done.stderr


def test_the_read_floor_grows_with_the_size_and_not_the_claim(tmp_path):
    small, large = sparse(tmp_path / "a.obj", 1 << 20), sparse(tmp_path / "b.obj", 1 << 30)
    assert mesh_source(large).read_floor() == 1024 * mesh_source(small).read_floor() >= 1 << 33
    assert mesh_source(tmp_path / "missing.obj").read_floor() == 0


def test_a_binary_stl_whose_size_does_not_match_its_count_is_corrupt(tmp_path):
    path = tmp_path / "cut.stl"
    path.write_bytes(b"\0" * 80 + (1000).to_bytes(4, "little") + b"\0" * 50 * 10)  # counts 1000, holds 10
    with pytest.raises(SceneError, match=r"cut\.stl.*binary STL.*1,000 triangles.*corrupt"):
        mesh_source(path).triangles()
    big = sparse(tmp_path / "zeros.stl", 1 << 30)  # a multi-GiB STL of zeros counts 0 but is 1 GiB
    with pytest.raises(SceneError, match="corrupt"):
        mesh_source(big).triangles()


def test_unused_vertices_count(tmp_path):
    """A million vertices and one face weigh as what they hold (before: one triangle)."""
    obj = tmp_path / "points.obj"
    obj.write_bytes(b"v 0 0 0\n" * 1_000_000 + b"f 1 2 3\n")
    assert mesh_source(obj).triangles() >= 999_000
    ply = tmp_path / "points.ply"
    ply.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000\nproperty float x\n"
                    b"property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                    b"end_header\n")
    assert mesh_source(ply).triangles() >= 999_000


def binary_ply(path: Path, vertices: int, element: str, lists: list[list[int]], count: str = "uint") -> Path:
    """A binary PLY of `vertices` zero vertices and one `element` (face, tristrips) a list, as the header says."""
    import struct
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\nproperty float x\n"
              f"property float y\nproperty float z\nelement {element} {len(lists)}\n"
              f"property list {count} int vertex_indices\nend_header\n").encode()
    packed = {"uchar": "<B", "uint": "<I", "int": "<i"}[count]
    body = b"".join(struct.pack(packed, len(entries)) + np.asarray(entries, "<i4").tobytes() for entries in lists)
    path.write_bytes(header + bytes(12 * vertices) + body)
    return path


def test_a_ply_s_lists_weigh_as_the_triangles_they_can_make(tmp_path):
    """Issue 30 item 3: a PLY face of 3 M corners (header: 1 face) and one strip of 10⁶ indices count as the
    3 M − 2 and 10⁶ − 2 triangles they make, not 1; so --max-memory 300M refuses the face before trimesh reads
    it (before: the count was 1, and `plan` ran over 6 minutes at 745 MB). A file of triangles counts exactly."""
    import random
    face = binary_ply(tmp_path / "face.ply", 3, "face", [[i % 3 for i in range(3_000_000)]])
    assert mesh_source(face).triangles() == 3_000_000 - 2
    strip = binary_ply(tmp_path / "strip.ply", 3, "tristrips", [[i % 3 for i in range(1_000_000)]], count="int")
    assert mesh_source(strip).triangles() == 1_000_000 - 2
    rng = random.Random(1)
    triangles = binary_ply(tmp_path / "t.ply", 500, "face", [rng.sample(range(500), 3) for _ in range(700)],
                           count="uchar")
    assert mesh_source(triangles).triangles() == 700
    done, peak, _ = run_measured(["render", str(face), "--max-memory", "300M", "-o", str(tmp_path / "o.png")],
                                 tmp_path)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and "3.0M triangles" in lines[0], done.stderr
    assert peak < 400 << 20


def reference_count(text: bytes) -> int:
    """An OBJ's triangles line by line, as the count was before (holding each line)."""
    faces = sum(max(len(line.split()) - 3, 0) for line in text.split(b"\n") if line[:2] in (b"f ", b"f\t"))
    vertices = sum(1 for line in text.split(b"\n") if line[:2] in (b"v ", b"v\t"))
    return max(faces, vertices - 2)


obj_lines = st.lists(st.one_of(
    st.builds(lambda n: b"f" + b" 1" * n, st.integers(0, 9)),
    st.builds(lambda n: b"f\t" + b"2 " * n, st.integers(0, 9)),
    st.just(b"v 1 2 3"), st.just(b"vn 0 0 1"), st.just(b"# f 1 2 3"), st.just(b""), st.just(b"  "),
    st.just(b"ff 1 2 3"), st.binary(max_size=6)), max_size=30)


@settings(max_examples=200, deadline=None)
@given(lines=obj_lines, chunk=st.integers(1, 9), newline=st.sampled_from([b"\n", b"\r\n"]))
def test_an_obj_is_counted_the_same_in_any_pieces(lines, chunk, newline):
    """The chunked count equals the line-by-line count wherever the pieces cut the lines."""
    text = newline.join(lines)
    if any(b"\n" in line or b"\r" in line for line in lines):
        text = b"\n".join(line.replace(b"\r", b" ").replace(b"\n", b" ") for line in lines)
    expected = reference_count(text)
    saved = obj_format.CHUNK
    try:
        obj_format.CHUNK = chunk
        assert obj_format.count(io.BytesIO(text), len(text), None) == max(expected, 0)
    finally:
        obj_format.CHUNK = saved


def test_a_one_line_obj_is_counted_in_bounded_memory(tmp_path):
    """16 MB on one line: the count holds 1 MB pieces and their index arrays, not the line (before: the line
    and its split, 500 MB)."""
    import tracemalloc
    path = tmp_path / "polygon.obj"
    corners = 8_000_000
    path.write_bytes(b"f" + b" 1" * corners)
    tracemalloc.start()
    try:
        count = mesh_source(path).triangles()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert count == corners - 2
    assert peak < 32 << 20, f"{peak >> 20} MB to count a 16 MB line"


def test_the_budget_follows_ulimit_v():
    """available_memory() is at most what RLIMIT_AS leaves (before: the machine's free memory only)."""
    probe = ("import resource; from raycast_phong.io.system import available_memory; "
             "resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30)); print(available_memory())")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=True)
    assert 0 <= int(done.stdout) < 3 << 30


def test_max_memory_caps_the_framing_read_and_is_cleared_after(tmp_path):
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    path = tmp_path / "a.obj"
    path.write_bytes(b"v 0 0 0\n" * 200_000 + b"f 1 2 3\n")
    done = CliRunner().invoke(app, ["plan", str(path), "--max-memory", "1M"])
    assert done.exit_code == 2 and "a.obj" in done.output and "memory" in done.output, done.output
    done = CliRunner().invoke(app, ["plan", str(path)])  # the next command of the process has no such cap
    assert done.exit_code == 2 and "every vertex of the model" in done.output, done.output  # read, then refused


def test_each_load_keeps_to_its_own_budget(tmp_path):
    """The budget is an argument down to the framing read (load_scene → read_scene_dict → mesh_scene_dict →
    check_mesh_read), not a module global the CLI set and cleared: loads in one process, one after the
    other with different budgets, each get their own."""
    path = tmp_path / "a.obj"
    path.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\n" * 70_000 + b"f 1 2 3\n")  # ≈ 1.8 MB: ≈ 22 MB to read
    for budget, fits in [(1 << 20, False), (1 << 30, True), (1 << 20, False), (None, True)]:
        if fits:
            assert rp.load_scene(path, max_memory=budget).objects[0].shape == "mesh"
        else:
            with pytest.raises(SceneError, match=r"a\.obj: reading its .* than the 1 MB available"):
                rp.load_scene(path, max_memory=budget)


def test_an_obj_of_a_polygon_and_no_vertices_is_one_line(tmp_path):
    """Found by test_fuzz_files: `f 1 1 1 1` alone made the concave-polygon pass index an empty vertex array
    (IndexError, 'internal error', exit 1)."""
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    (tmp_path / "h.obj").write_bytes(b"f 1 1 1 1")
    done = CliRunner().invoke(app, ["plan", str(tmp_path / "h.obj"), "--max-memory", "50M"])
    assert done.exit_code == 2 and len(done.output.strip().splitlines()) == 1, done.output
    assert "holds no triangles" in done.output


def test_a_file_of_exactly_the_limit_opens_and_one_byte_more_is_refused(tmp_path):
    """open_regular's `limit` is the most bytes allowed: a file that long opens, one byte longer is one line."""
    from raycast_phong.errors import SceneError
    from raycast_phong.io.files import open_regular
    path = tmp_path / "s.toml"
    path.write_bytes(b"#" * 4096)
    with open_regular(path, "s.toml", "scene file", limit=4096) as handle:
        assert len(handle.read()) == 4096
    with pytest.raises(SceneError, match=r"the scene file is 4,096 bytes, more than the 4,095"):
        open_regular(path, "s.toml", "scene file", limit=4095)


@pytest.mark.parametrize("piped", [False, True], ids=["file", "stdin"])
def test_a_scene_of_exactly_max_scene_bytes_reads_and_one_byte_more_is_refused(tmp_path, monkeypatch, piped):
    """read_scene_file's own cap, for a file and for `-` (standard input, which no fstat measures): a scene of
    exactly MAX_SCENE_BYTES (here patched to 4 KiB) parses, one byte more is one line. Catches its `>` made `>=` and
    stdin read only MAX_SCENE_BYTES bytes (a longer scene then cut to the limit and parsed), and a file's size
    checked against a larger limit than its read (refused then only after reading, without its size)."""
    from raycast_phong.io import scene_file
    monkeypatch.setattr(scene_file, "MAX_SCENE_BYTES", 4096)
    text = b'[render]\nwidth = 8\n'
    exact = text + b"#" * (4096 - len(text))

    def read(data: bytes) -> dict:
        if not piped:
            (tmp_path / "s.toml").write_bytes(data)
            return scene_file.read_scene_file(tmp_path / "s.toml")
        monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
        return scene_file.read_scene_file(Path("-"))

    assert read(exact) == {"render": {"width": 8}}
    said = r"the scene is more than the" if piped else r"the scene file is 4,097 bytes, more than the 4,096"
    with pytest.raises(SceneError, match=said):  # a file is measured before it is read, and its size said
        read(exact + b"#")


def test_a_name_of_exactly_the_shown_length_is_kept_whole_and_one_more_is_shortened():
    """shown_name keeps a quoted name of up to SHOWN_NAME_CHARACTERS (100) characters whole: 98 letters quote
    to exactly 100 and stay as they are; 99 quote to 101 and keep their first and last 50 characters, saying
    the one left out."""
    from raycast_phong.io.files import shown_name
    assert shown_name("a" * 98) == "'" + "a" * 98 + "'"
    assert shown_name("a" * 99) == "'" + "a" * 49 + "…(1 characters)…" + "a" * 49 + "'"


def test_a_file_replaced_by_another_of_the_same_size_and_time_is_a_new_version(tmp_path):
    """file_version must tell a file swapped in under the same name (same size, mtime set back, as a copy
    with preserved times gives) from the one read before: its inode differs, so what was learnt of the old
    file (its bounds, its triangles) is not taken for the new one's."""
    from raycast_phong.io.files import file_version
    path = tmp_path / "mesh.obj"
    path.write_bytes(b"one")
    before, info = file_version(path), os.stat(path)
    swapped = tmp_path / "swapped.obj"
    swapped.write_bytes(b"two")  # made while the first still exists: another inode
    os.utime(swapped, ns=(info.st_atime_ns, info.st_mtime_ns))
    os.replace(swapped, path)
    now = os.stat(path)
    assert (now.st_size, now.st_mtime_ns) == (info.st_size, info.st_mtime_ns)
    assert file_version(path) != before
