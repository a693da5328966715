"""One read per file (issue 33): a mesh file's JSON and its .mtl are read and parsed once for one render,
however many stages (framing, the memory estimate's counts and texture sizes, the read's checks, batch's side
files) want what they say. On main before io/meshes/source.py: a .gltf's JSON was parsed 7 times for one render
(6 by this renderer, 1 by trimesh), an OBJ's .mtl opened twice."""

from __future__ import annotations

import builtins
import io
import json
import os
import shutil
from pathlib import Path

import trimesh

import raycast_phong as rp

MODELS = Path(__file__).resolve().parents[1] / "data" / "models"
SIZE = ["render.width=24", "render.height=18"]


def _count_opens(monkeypatch, suffix: str) -> list[str]:
    """Every open of a file ending in `suffix`, by os.open (io.files.open_regular) or io.open (Path.read_text)."""
    opened: list[str] = []
    real_os, real_io = os.open, io.open

    def os_open(path, *args, **kwargs):
        if str(path).endswith(suffix):
            opened.append(str(path))
        return real_os(path, *args, **kwargs)

    def io_open(path, *args, **kwargs):
        if isinstance(path, (str, Path)) and str(path).endswith(suffix):
            opened.append(str(path))
        return real_io(path, *args, **kwargs)
    monkeypatch.setattr(os, "open", os_open)
    monkeypatch.setattr(io, "open", io_open)
    monkeypatch.setattr(builtins, "open", io_open)
    return opened


def test_a_textured_obj_s_mtl_is_read_once_for_one_render(tmp_path, monkeypatch):
    for name in ("fuze.obj", "fuze.obj.mtl", "fuze uv.jpg"):
        shutil.copy(MODELS / name, tmp_path / name)
    opened = _count_opens(monkeypatch, ".mtl")
    result = rp.render_file(tmp_path / "fuze.obj", SIZE)
    assert result.image.max() > 0  # the model is there, textured
    assert opened == [str(tmp_path / "fuze.obj.mtl")], opened


def test_a_gltf_s_json_is_parsed_once_here_for_one_render(tmp_path, monkeypatch):
    """Once, by this renderer (its MeshSource): the geometry, materials and image are read from that parse
    (io/meshes/gltf_parts.py); trimesh, which parsed it again, no longer reads such a file."""
    scene = trimesh.load(MODELS / "BoxTextured.glb")
    for name, data in scene.export(file_type="gltf").items():
        (tmp_path / name).write_bytes(data)
    text = (tmp_path / "model.gltf").read_bytes()
    parses = []
    real = json.loads

    def loads(value, *args, **kwargs):
        if value in (text, text.decode("utf-8")):
            parses.append(1)
        return real(value, *args, **kwargs)
    monkeypatch.setattr(json, "loads", loads)
    result = rp.render_file(tmp_path / "model.gltf", SIZE)
    assert result.image.max() > 0 and result.triangles == 12
    assert len(parses) == 1, len(parses)


def test_a_batch_frames_only_the_meshes_it_renders(tmp_path, monkeypatch):
    """A mesh file rendered directly is framed (read whole, through trimesh) to place its camera; a batch whose
    image of it is up to date does not read it so (its hash and inputs come from the MeshSource). An edited
    .mtl makes it render again, with one read: framing's, which the render takes."""
    import json as json_module

    from typer.testing import CliRunner

    from raycast_phong.cli import app
    from raycast_phong.io.meshes import read as mesh_file
    for name in ("fuze.obj", "fuze.obj.mtl", "fuze uv.jpg"):
        shutil.copy(MODELS / name, tmp_path / name)
    out, runner = tmp_path / "out", CliRunner()
    command = ["batch", str(tmp_path / "fuze.obj"), "--out", str(out), "--jobs", "1", "--quiet"]

    def status() -> str:
        return json_module.loads((out / "manifest.json").read_text(encoding="utf-8"))["scenes"]["fuze"]["status"]
    assert runner.invoke(app, command).exit_code == 0 and status() == "rendered"
    reads = []
    real = mesh_file.read_file
    monkeypatch.setattr(mesh_file, "read_file", lambda *a, **k: reads.append(a[0].path) or real(*a, **k))
    assert runner.invoke(app, command).exit_code == 0 and status() == "up to date"
    assert reads == []
    mtl = tmp_path / "fuze.obj.mtl"
    mtl.write_text(mtl.read_text(encoding="utf-8").replace("Kd ", "Kd 0.5 0.5 0.5 #", 1), encoding="utf-8")
    os.utime(mtl, ns=(1, 1))
    assert runner.invoke(app, command).exit_code == 0 and status() == "rendered"
    assert reads == [tmp_path / "fuze.obj"]


def _obj_with_mtl(folder: Path, kd: str) -> tuple[Path, Path]:
    obj, mtl = folder / "m.obj", folder / "m.mtl"
    obj.write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl own\nf 1 2 3\n", encoding="utf-8")
    mtl.write_text(f"newmtl own\nKd {kd}\n", encoding="utf-8")
    return obj, mtl


def _edit(path: Path, text: str) -> None:
    """Rewrite `path` with `text` of the same size, its mtime a second later: only the version tells."""
    before = path.stat()
    assert len(text.encode()) == before.st_size
    path.write_text(text, encoding="utf-8")
    os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns + 1_000_000_000))


def test_an_edited_mtl_makes_the_obj_s_source_stale(tmp_path):
    """Catches MeshSource.current() (and identity) checking the .obj alone: an .mtl edited since is not seen."""
    from raycast_phong.geometry.build import build_geometry
    from raycast_phong.geometry.memo import BuildMemo
    from raycast_phong.io.meshes.source import mesh_source, mesh_sources
    obj, mtl = _obj_with_mtl(tmp_path, "0.9 0.1 0.1")
    source = mesh_source(obj)
    assert source.side_files == (mtl,) and source.current()
    scene = rp.validate_scene({"objects": [{"shape": "mesh", "path": "m.obj"}]}, folder=tmp_path)
    memo = BuildMemo()
    assert build_geometry(scene, memo=memo).file_materials[0, 3:6].tolist() == [0.9, 0.1, 0.1]
    _edit(mtl, "newmtl own\nKd 0.1 0.9 0.1\n")
    assert not source.current()
    assert mesh_source(obj).identity != source.identity
    fresh = mesh_sources(scene, {str(obj.resolve()): source})[obj]
    assert fresh is not source and fresh.current()
    assert build_geometry(scene, memo=memo).file_materials[0, 3:6].tolist() == [0.1, 0.9, 0.1]
    mtl.unlink()
    assert not fresh.current()
