"""A plain OBJ (v and f lines only) read by one compiled pass (io/meshes/obj_plain.py) gives what trimesh's reader gave:
the same MeshFile, array for array and bit for bit; every other OBJ is left to the full reader."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import trimesh

from raycast_phong.errors import SceneError
from raycast_phong.io.meshes import obj_plain
from raycast_phong.io.meshes import read as mesh_file
from raycast_phong.io.meshes.obj_plain import plain_obj
from raycast_phong.io.meshes.source import mesh_source, read_mesh

pytestmark = pytest.mark.usefixtures("in_tmp_path")


def read(path: Path, plain: bool, monkeypatch) -> mesh_file.MeshFile:
    with monkeypatch.context() as patch:
        if not plain:
            patch.setattr(obj_plain, "plain_obj", lambda data, path: None)
        return mesh_file.read_file(mesh_source(path), bounds=True)  # no cache: read each time


def assert_same_mesh_file(a: mesh_file.MeshFile, b: mesh_file.MeshFile) -> None:
    for field in dataclasses.fields(mesh_file.MeshFile):
        x, y = getattr(a, field.name), getattr(b, field.name)
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), field.name
        elif isinstance(x, float):
            assert np.float64(x).tobytes() == np.float64(y).tobytes(), field.name
        else:
            assert x == y, field.name


def random_plain(seed: int) -> bytes:
    """A plain OBJ with what such files hold: comments, blank lines, CRLF, tabs, exponents, v lines among the
    faces, vertices no face names, no newline at the end."""
    rng = np.random.default_rng(seed)
    count = int(rng.integers(4, 60))
    points = rng.normal(size=(count, 3)) * 10.0 ** rng.integers(-3, 4)
    faces = rng.integers(1, count + 1, size=(int(rng.integers(1, 80)), 3))
    words = [f"{x:.{int(rng.integers(1, 12))}g}" for x in points.ravel()]
    lines = ["# made by a test", ""]
    lines += [f"v {' '.join(words[3 * i:3 * i + 3])}" for i in range(count // 2)]
    lines += ["f  " + "\t ".join(map(str, face)) + " " for face in faces[: len(faces) // 2]]
    lines += [f"v {' '.join(words[3 * i:3 * i + 3])}" for i in range(count // 2, count)]
    lines += ["f " + " ".join(map(str, face)) for face in faces[len(faces) // 2:]]
    ending = "\r\n" if seed % 2 else "\n"
    return ending.join(lines).encode()


@pytest.mark.parametrize("seed", range(8))
def test_a_plain_obj_reads_as_trimesh_read_it(seed, tmp_path, monkeypatch):
    path = tmp_path / "plain.obj"
    path.write_bytes(random_plain(seed))
    assert plain_obj(path.read_bytes(), path) is not None
    assert_same_mesh_file(read(path, True, monkeypatch), read(path, False, monkeypatch))


def test_a_plain_obj_does_not_go_through_trimeshs_text_reader(tmp_path, monkeypatch):
    """trimesh's reader spent Python per face line: 2.5 of bunny-1m's 3 s."""
    path = tmp_path / "plain.obj"
    path.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n")

    def refuse(*args, **kwargs):
        raise AssertionError("trimesh's OBJ reader was called for a plain file")

    monkeypatch.setattr(trimesh.exchange.obj, "load_obj", refuse)
    assert len(read_mesh(path, str(path)).faces) == 2


@pytest.mark.parametrize("text", [
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n",
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n",
    b"mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n",
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\n# usemtl red\nf 1 2 3\n",  # trimesh's reader acts on it
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\n",  # a polygon
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n",  # relative indices
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",  # index 0: the full reader's words
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",  # past the vertices
    b"v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    b"v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n",
    b"v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n",  # colours
    b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    b"v 1-e5 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",  # trimesh rewrites -e
    b"v 1..2 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",  # not a number
    b"v 0 0 0 # a point\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    b"o thing\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    b"g part\nv 0 0 0\nv 1 0 0\nv 0 1 0\ns 1\nf 1 2 3\n",
    b" v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    b"# a comment \\\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n",  # continued: the comment takes the line
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\n",  # no faces
])
def test_any_other_obj_is_left_to_the_full_reader(text, tmp_path, monkeypatch):
    path = tmp_path / "other.obj"
    path.write_bytes(text)
    assert plain_obj(text, path) is None


WORDS = ["-0", "0.000", "+1.5", ".5", "5.", "1E5", "1e+17", "1e-22", "1e-23", "4.9e-324", "1e-310",
         "9007199254740993", "0.1", "123456789012345678", "-2.2250738585072014e-308",
         "3.14159265358979323846", "00012.5000", "7e0", "-.25e-3", "1234567890123456e-5"]


def test_every_way_of_writing_a_coordinate_reads_as_trimesh_read_it(tmp_path, monkeypatch):
    """Coordinates in and beyond the compiled reader's exact path (more than 2^53, exponents past ±22, subnormal),
    and one file wholly inside it: the bits trimesh's reader gave."""
    faces = "f 1 2 3\nf 2 3 4\n"
    for words in (WORDS, [*WORDS[:8], "0.12794000", "-0.03783000", "1e0", "42"]):
        rows = [words[i:i + 3] + ["1"] * (3 - len(words[i:i + 3])) for i in range(0, len(words), 3)]
        path = tmp_path / f"words{len(words)}.obj"
        path.write_text("".join(f"v {' '.join(row)}\n" for row in rows) + faces)
        assert plain_obj(path.read_bytes(), path) is not None
        assert_same_mesh_file(read(path, True, monkeypatch), read(path, False, monkeypatch))


def test_the_exact_path_reads_what_python_reads(monkeypatch):
    """decimals.decimal's value is float()'s wherever it answers, over random words."""
    from raycast_phong.io.meshes.decimals import POWERS, decimal
    rng = np.random.default_rng(5)
    answered = 0
    for _ in range(3000):
        digits = "".join(rng.choice(list("0123456789"), size=int(rng.integers(1, 19))))
        cut = int(rng.integers(0, len(digits) + 1))
        word = ("-" if rng.random() < 0.5 else "") + digits[:cut] + "." + digits[cut:]
        if rng.random() < 0.5:
            word += f"e{int(rng.integers(-30, 31))}"
        data = np.frombuffer(word.encode(), np.uint8)
        value, exact = decimal(data, 0, len(data), POWERS)
        if exact:
            answered += 1
            assert np.float64(value).tobytes() == np.float64(float(word)).tobytes(), word
    assert answered > 1000


def test_a_face_index_of_19_digits_is_refused_not_wrapped(tmp_path):
    """The fast path reads a face index of at most 18 digits (below 2^63); 19 nines would wrap an int64 to a
    negative number. Such a file must leave the fast path and be refused in one line as an index beyond the
    3 vertices, never read as some other vertex nor crash."""
    path = tmp_path / "big.obj"
    path.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9999999999999999999\n")
    assert plain_obj(path.read_bytes(), path) is None
    with pytest.raises(SceneError):
        mesh_source(path).read()
