"""Every format in the registry (io/meshes/__init__.py, FORMATS) held to one contract: a small file of it reads to
its triangles, is counted and weighed before the read, is read once for framing and render, and bad input (empty,
cut short, noise, another format's bytes under its suffix) is one line, never a traceback. And nothing outside
io/meshes/ names a mesh suffix: a format has one home."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
import trimesh

import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.io.meshes import FORMATS, format_of, is_mesh_file
from raycast_phong.io.meshes import read as mesh_read
from raycast_phong.io.meshes.source import mesh_source

PACKAGE = Path(rp.__file__).parent
SUFFIXES = [suffix for kind in FORMATS for suffix in kind.suffixes]
# A tetrahedron wound outward: 4 triangles, every format can hold it.
TETRA = trimesh.Trimesh([[1, 1, 1], [-1, -1, 1], [-1, 1, -1], [1, -1, -1]],
                        [[0, 1, 3], [0, 2, 1], [0, 3, 2], [1, 2, 3]], process=False)
SMALL = ["render.width=24", "render.height=18"]


def write(folder: Path, suffix: str) -> Path:
    """The tetrahedron in the format of `suffix`, written by trimesh's exporters (an independent writer)."""
    path = folder / f"tetra{suffix}"
    data = TETRA.export(file_type=suffix[1:])
    if isinstance(data, dict):  # a .gltf and its buffer files
        for name, content in data.items():
            (path if name.endswith(suffix) else folder / name).write_bytes(content)
    else:
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
    return path


def test_the_registry_claims_each_suffix_once_and_names_it():
    assert len(SUFFIXES) == len(set(SUFFIXES))
    for kind in FORMATS:
        assert len(kind.names) == len(kind.suffixes) and all(s == s.lower() and s[0] == "." for s in kind.suffixes)
        for suffix in kind.suffixes:
            assert format_of(Path(f"x{suffix.upper()}")) is kind and is_mesh_file(f"a/b{suffix}")
    assert not is_mesh_file("scene.toml") and not is_mesh_file("noext")


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_a_small_file_of_each_format_reads_counts_and_renders(tmp_path, suffix):
    path = write(tmp_path, suffix)
    source = mesh_source(path)
    read = source.read()
    assert len(read.faces) == 4 and read.vertices.shape[1] == 3
    corners = np.asarray(read.vertices)[read.faces]
    area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1).sum() / 2
    assert area == pytest.approx(TETRA.area, rel=1e-6)  # the same surface, placed as written
    # Counted before the read: at least the triangles (never fewer, or the estimate under-counts), at most the
    # size bound; the read floor at least the file's own bytes.
    assert 4 <= mesh_source(path).triangles() <= max(4, path.stat().st_size)
    assert source.read_floor() >= path.stat().st_size
    scene = rp.load_scene(path, SMALL)
    result = rp.render(scene)  # drawn: some pixel is not the background (trimesh writes a COLLADA material black)
    assert result.triangles == 4 and (np.abs(result.image - np.float32(scene.render.background)) > 0.05).any()


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_a_file_is_read_once_for_framing_and_render(tmp_path, suffix, monkeypatch):
    path = write(tmp_path, suffix)
    reads = []
    real = mesh_read.read_file
    monkeypatch.setattr(mesh_read, "read_file", lambda *a, **k: reads.append(a[0].path) or real(*a, **k))
    rp.render(rp.load_scene(path, SMALL))
    assert reads == [path]


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_a_file_named_in_capitals_renders_as_the_same_file_in_lower_case(tmp_path, suffix):
    """Windows and some exporters write MODEL.PLY, model.Obj: every stage that looks at the suffix (the format,
    the content check, the count and the read floor, framing's colour space, the reader) takes it in any case, so
    the capitalised copy renders bit for bit as the original. A stage comparing the suffix as written fails here."""
    (tmp_path / "lower").mkdir()
    (tmp_path / "upper").mkdir()
    lower, upper_folder = write(tmp_path / "lower", suffix), tmp_path / "upper"
    for file in lower.parent.iterdir():  # a .gltf's buffer files keep their names: the document names them
        target = upper_folder / (file.stem + file.suffix.upper() if file == lower else file.name)
        target.write_bytes(file.read_bytes())
    upper = upper_folder / (lower.stem + suffix.upper())
    assert mesh_source(upper).triangles() == mesh_source(lower).triangles()
    assert mesh_source(upper).read_floor() == mesh_source(lower).read_floor()
    np.testing.assert_array_equal(rp.render(rp.load_scene(upper, SMALL)).image,
                                  rp.render(rp.load_scene(lower, SMALL)).image)


NOISE = bytes(np.random.default_rng(7).integers(0, 256, 700, dtype=np.uint8))


@pytest.mark.parametrize("suffix", SUFFIXES)
@pytest.mark.parametrize("bad", ["empty", "cut", "noise", "other"])
def test_bad_bytes_of_each_format_are_one_line(tmp_path, suffix, bad):
    good = write(tmp_path, suffix).read_bytes()
    other = write(tmp_path, ".ply" if suffix != ".ply" else ".obj").read_bytes()
    data = {"empty": b"", "cut": good[: len(good) // 3], "noise": NOISE, "other": other}[bad]
    path = tmp_path / f"bad{suffix}"
    path.write_bytes(data)
    try:
        read = mesh_source(path, "scene.toml: objects.0.path").read()
    except SceneError as error:
        text = str(error)
        assert "\n" not in text and text.startswith("scene.toml: objects.0.path: ") and str(path) in text, text
        return
    # A reader may still find triangles in a file cut short or in noise (an OBJ's first lines): then they are
    # whole, finite triangles of the file's own vertices.
    assert bad in ("cut", "noise") and len(read.faces) and np.isfinite(read.vertices[read.faces]).all()


def test_no_module_outside_io_meshes_names_a_mesh_suffix():
    """A format's suffixes are its record's (MeshFormat.suffixes); a stage that compares a suffix is a format
    rule without its home. Scene and image suffixes are not mesh formats."""
    named = []
    for path in PACKAGE.rglob("*.py"):
        if path.parent.name == "meshes":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names = {id(part) for node in ast.walk(tree) if isinstance(node, ast.JoinedStr) for part in node.values}
        for node in ast.walk(tree):  # a constant, not a file name written in an f-string (f"{stem}.obj")
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.lower() in SUFFIXES \
                    and id(node) not in names:
                named.append(f"{path.relative_to(PACKAGE)}:{node.lineno}: {node.value!r}")
    assert not named


# Another format's bytes under each suffix, and what they are called: a binary file announces itself (PLY, GLB,
# a zip); every format but COLLADA (XML, whose reader says what is wrong) refuses them before its reader runs
# (an OBJ named .stl was read as a binary STL of 433 GB).
IMPOSTORS = {".ply": (".glb", "GLB")}


@pytest.mark.parametrize("suffix", [s for s in SUFFIXES if s != ".dae"])
def test_another_format_s_bytes_are_refused_before_any_reader(tmp_path, suffix):
    other, name = IMPOSTORS.get(suffix, (".ply", "PLY"))
    path = tmp_path / f"impostor{suffix}"
    path.write_bytes(write(tmp_path, other).read_bytes())
    with pytest.raises(SceneError, match=f"its content is {name}; rename it"):
        mesh_source(path, "t").read()


def test_a_sparse_file_too_large_to_read_is_refused_from_its_size_alone(tmp_path, monkeypatch):
    """A 3 GiB one-line OBJ (sparse: no disk) is refused from `stat` and its format's read floor, before its
    `mtllib` scan, its triangle count or any read (all three made fail here): it cost 7.5 s of CPU to refuse."""
    from raycast_phong.io.meshes import obj as obj_format
    from raycast_phong.io.meshes import size
    path = tmp_path / "huge.obj"
    with open(path, "wb") as handle:
        handle.write(b"v 0 0 0\n")
        handle.truncate(3 << 30)
    fail = lambda *a, **k: pytest.fail("the file was scanned, counted or read")
    for module, name in ((obj_format, "scan_mtllib"), (size, "count_triangles"), (mesh_read, "read_file")):
        monkeypatch.setattr(module, name, fail)
    with pytest.raises(SceneError, match=r"needs ≈ .* of memory, more than the 1 GB available"):
        rp.load_scene(path, max_memory=1 << 30)


def test_a_scene_over_the_budget_is_refused_before_any_kernel_is_made_ready(tmp_path, monkeypatch):
    """`render` checks the memory before it loads or compiles a kernel: with an empty cache a refused scene
    compiled for 27 s first."""
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    from raycast_phong.renderer import warmup
    write(tmp_path, ".ply")
    (tmp_path / "scene.toml").write_text('[[objects]]\nshape = "mesh"\npath = "tetra.ply"\n'
                                         '[[objects]]\nshape = "icosphere"\nsubdivisions = 8\n', encoding="utf-8")
    monkeypatch.setattr(warmup, "ready_kernels", lambda *a, **k: pytest.fail("kernels made ready"))
    done = CliRunner().invoke(app, ["render", str(tmp_path / "scene.toml"), "-o", str(tmp_path / "x.png"),
                                    "--max-memory", "20M"])
    assert done.exit_code == 2, done.output
    assert "above the 20 MB budget" in done.stderr and "\n" not in done.stderr.strip()


def refused_render(path: Path) -> str:
    """`render PATH -o x.png` beside it: exit 2, no image, and its one stderr line."""
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    done = CliRunner().invoke(app, ["render", str(path), "-o", str(path.parent / "x.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert not (path.parent / "x.png").exists()
    return line


@pytest.mark.parametrize("name, content, said", [
    ("model.fbx", b"; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n", "its format is FBX"),  # ASCII FBX
    ("model.fbx", b"Kaydara FBX Binary  \x00\x1a\x00\xe8\x1c\x00\x00", "its format is FBX"),
    ("chair.blend", b"BLENDER-v300REND", "its format is Blender"),
    ("scene.toml", (Path(__file__).parents[2] / "docs" / "images" / "default.png").read_bytes()[:4096],
     "its format is a PNG image"),
    ("scene.toml", b"BLENDER-v300REND\x00\x00", "its format is Blender"),
])
def test_a_format_not_read_is_named_with_those_that_are_not_read_as_toml(tmp_path, name, content, said):
    """An FBX (what students download most) said "TOML syntax error ... line 1, column 7", a PNG named .toml a
    utf-8 decode error: each is now one line naming its format, the formats read and, for a model, how to convert."""
    path = tmp_path / name
    path.write_bytes(content)
    line = refused_render(path)
    assert line.startswith(f"error: {path}: {said}, which this renderer does not read; it reads scene files"), line
    assert "OBJ, PLY, STL, OFF, glTF/GLB, 3MF, COLLADA" in line
    assert ("convert it to glTF" in line) == (said != "its format is a PNG image")


@pytest.mark.parametrize(("name", "text", "said"), [
    ("README.md", "# A title\n\nSome text, not a scene.\n", "not a scene file (read as TOML: "),
    ("scene.toml", "a = \n", "TOML syntax error: "),  # a scene with a mistake: said as one
    ("scene", "a = \n", "TOML syntax error: "),  # no suffix: a scene, as TOML
])
def test_a_text_file_that_is_no_scene_is_said_to_be_none(tmp_path, name, text, said):
    """`render README.md` said "TOML syntax error: Expected '=' ..." as if the file were a broken scene; a file of
    another suffix that is not TOML is said to be no scene, with what is read. A .toml keeps its syntax error."""
    path = tmp_path / name
    path.write_text(text)
    line = refused_render(path)
    assert line.startswith(f"error: {path}: {said}"), line
    assert ("allowed: a scene file (.toml, .json) or a mesh file (OBJ, PLY" in line) == (name == "README.md"), line


def test_a_node_transform_turns_normals_by_its_inverse_transpose():
    """format.placed: a normal stays perpendicular to the placed surface. Under a scale of (2, 1, 1) a surface's
    tangent (1, -1, 0) becomes (2, -1, 0), so its normal (1, 1, 0)/√2 must become (1, 2, 0)/√5 (n L⁻¹ by hand:
    (0.5, 1, 0)), not (2, 1, 0) as the matrix itself (or its transpose) would turn it. Under random matrices
    every tangent stays perpendicular to the turned normal, and a mirror turns the faces over."""
    from raycast_phong.io.meshes.format import placed
    matrix = np.diag([2.0, 1.0, 1.0, 1.0])
    matrix[:3, 3] = (5, 0, 0)
    normal = np.array([[1.0, 1.0, 0.0]]) / np.sqrt(2)
    vertices, faces, normals = placed(np.array([[1.0, -1.0, 0.0]]), np.array([[0, 1, 2]]), normal, matrix)
    np.testing.assert_allclose(vertices, [[7.0, -1.0, 0.0]])
    np.testing.assert_allclose(normals / np.linalg.norm(normals), [[1 / np.sqrt(5), 2 / np.sqrt(5), 0]], atol=1e-12)
    np.testing.assert_array_equal(faces, [[0, 1, 2]])
    rng = np.random.default_rng(3)
    for _ in range(20):
        linear = rng.normal(size=(3, 3))
        turned = np.eye(4)
        turned[:3, :3] = linear
        n = rng.normal(size=3)
        tangent = np.cross(n, rng.normal(size=3))  # perpendicular to n
        _, faces, normals = placed(np.zeros((1, 3)), np.array([[0, 1, 2]]), n[None], turned)
        assert abs(normals[0] @ (linear @ tangent)) < 1e-9 * np.linalg.norm(normals) * np.linalg.norm(linear @ tangent)
        assert faces.tolist() == ([[2, 1, 0]] if np.linalg.det(linear) < 0 else [[0, 1, 2]])
