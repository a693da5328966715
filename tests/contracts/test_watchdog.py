"""A memory watchdog over every command (issue 21, "Done when"): each CLI command, on a hostile input, with a
200 MB budget (--max-memory 200M where the command has it, and for all of them a cgroup whose memory.max is
200 MB: io.system's cgroup root pointed at a fake tree), run in a fresh process whose peak resident size is
read from the wrapper's children's ru_maxrss. Each stays within the budget above the process's own peak: the
larger of `--help`'s (the interpreter and the CLI, 25 MB) and an 8×8 render's (numba, Embree and the kernels
loaded, ≈ 210 MB), as the budget counts bytes above a warmed-up process (renderer/budget.py). And the cgroup
limit, lower than the free memory, is what the budget follows."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from test_image_guards import claiming_png

from raycast_phong.io import system

CLI = [sys.executable, "-m", "raycast_phong.cli"]
BUDGET = 200 << 20
PROBE = ("import resource, subprocess, sys; done = subprocess.run(sys.argv[1:], capture_output=True, text=True, "
         "stdin=subprocess.DEVNULL, timeout=240); sys.stderr.write(done.stderr[-4000:]); "
         "print(done.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")


def fake_cgroup(folder: Path, limit: int, used: int = 0) -> Path:
    """A cgroup v2 tree whose root says memory.max = limit, memory.current = used."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "memory.max").write_text(f"{limit}\n")
    (folder / "memory.current").write_text(f"{used}\n")
    return folder


def under_cgroup(cgroup: Path) -> dict[str, str]:
    """The environment of processes (and their children) that read `cgroup` as their cgroup tree: a
    sitecustomize beside it, first on PYTHONPATH, sets io.system's root at start-up. The program itself reads
    no variable for this (issue 30 item 10: no test hook in production)."""
    site = cgroup.parent / f"{cgroup.name}-site"
    site.mkdir(exist_ok=True)
    (site / "sitecustomize.py").write_text(f"import raycast_phong.io.system as system\n"
                                           f"system._CGROUP_ROOT = {str(cgroup)!r}\n")
    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(site), os.environ.get("PYTHONPATH")]))}


def measured(args: list[str], cwd: Path, cgroup: Path) -> tuple[int, int, str]:
    """(exit status, peak resident bytes, stderr) of the CLI with `args` in a fresh process, under the fake
    cgroup; the wrapper is a process of its own, so ru_maxrss is this command's peak alone."""
    env = under_cgroup(cgroup)
    done = subprocess.run([sys.executable, "-c", PROBE, *CLI, *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)
    code, peak = map(int, done.stdout.split()[-2:])
    return code, peak * 1024, done.stderr


@pytest.fixture(scope="module")
def hostile(tmp_path_factory) -> Path:
    """A 512 MB sparse OBJ that claims one vertex, a scene of four icospheres of subdivision 8 (≈ 3.3 GB to
    render), PNGs claiming 20000 × 20000 pixels, a batch folder of the first two."""
    folder = tmp_path_factory.mktemp("hostile")
    with open(folder / "huge.obj", "wb") as handle:
        handle.write(b"v 0 0 0\n")
        handle.truncate(512 << 20)
    (folder / "bomb.toml").write_text('[[objects]]\nshape = "icosphere"\nsubdivisions = 8\n' * 4)
    claiming_png(folder / "a.png", 20000, 20000)
    claiming_png(folder / "b.png", 20000, 20000)
    (folder / "in").mkdir()
    (folder / "in" / "bomb.toml").write_text((folder / "bomb.toml").read_text())
    (folder / "in" / "huge.obj").symlink_to(folder / "huge.obj")
    fake_cgroup(folder / "cgroup", BUDGET)
    return folder


LIMIT = ["--max-memory", "200M"]
COMMANDS = {  # every command of `raycast-phong --help`, on the input most likely to make it allocate
    "render": ["render", "huge.obj", *LIMIT, "-o", "out.png"],
    "plan": ["plan", "bomb.toml", *LIMIT],
    "side-by-side": ["side-by-side", "huge.obj", "--vary", "render.shading=flat,phong", *LIMIT, "-o", "s.png"],
    "compare": ["compare", "a.png", "b.png", *LIMIT],
    "reference": ["reference", "--fine", "6", *LIMIT, "-o", "ref.exr"],
    "study": ["study", "bomb.toml", "--levels", "8", *LIMIT, "--out", "study"],
    "stability": ["stability", "--case", "watertightness"],  # no input of its own: the cgroup is its budget
    "batch": ["batch", "in", "--out", "batch", "--jobs", "2", *LIMIT],
    "view": ["view", "huge.obj", "--no-browser", "--port", "0"],
    "scene": ["scene", "huge.obj"],
    "schema": ["schema"],
}


def test_the_watchdog_covers_every_command():
    done = subprocess.run([*CLI, "--help"], capture_output=True, text=True, timeout=120, check=True)
    listed = [line.split()[1] for line in done.stdout.split("Commands")[1].splitlines()
              if line.startswith("│ ") and line[2] != " "]  # a command's first line; its help wraps indented
    assert sorted(listed) == sorted(COMMANDS)


@pytest.fixture(scope="module")
def baseline(hostile) -> int:
    """The process's own peak: the larger of `--help` (the CLI and typer) and a warmed-up 8×8 render."""
    peaks = []
    for args in (["--help"], ["render", "--width", "8", "--height", "8", "-o", "tiny.png", "-q"]):
        code, peak, stderr = measured(args, hostile, hostile / "cgroup")
        assert code == 0, stderr
        peaks.append(peak)
    return max(peaks)


@pytest.mark.slow
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_on_hostile_input_stays_within_its_budget(command, hostile, baseline):
    """Refused in one line (exit 2; batch: its two scenes fail, exit 1) or done, and the peak resident size
    stays within the 200 MB budget above the process's own (measured 2026-12-01: render 122 MB, plan 110,
    side-by-side 153, compare 79, reference 210, study 324, stability 179, batch 257, view 162, scene 153,
    schema 45; the baseline 212)."""
    code, peak, stderr = measured(COMMANDS[command], hostile, hostile / "cgroup")
    assert "Traceback" not in stderr, stderr
    assert code in (0, 1, 2), (code, stderr)
    if command in ("render", "plan", "side-by-side", "compare", "reference", "study", "view", "scene"):
        assert code == 2 and len(stderr.strip().splitlines()) == 1, stderr
    assert peak <= baseline + BUDGET, (f"{command}: peak {peak >> 20} MB, above the {BUDGET >> 20} MB budget over "
                                       f"the process's own {baseline >> 20} MB")


def test_a_cgroup_limit_below_the_free_memory_wins(tmp_path):
    """v2 and v1 trees, the process's own cgroup and a tighter parent: the room left is the least
    limit − usage (the machine has gigabytes free)."""
    v2 = fake_cgroup(tmp_path / "v2" / "a" / "b", 300 << 20, 100 << 20)
    (v2.parent / "memory.max").write_text("max\n")
    assert system._cgroup_room(tmp_path / "v2", ["0::/a/b"]) == 200 << 20
    fake_cgroup(v2.parent, 150 << 20, 100 << 20)  # the parent leaves less
    assert system._cgroup_room(tmp_path / "v2", ["0::/a/b"]) == 50 << 20
    v1 = tmp_path / "v1" / "memory" / "x"
    v1.mkdir(parents=True)
    (v1 / "memory.limit_in_bytes").write_text(f"{500 << 20}\n")
    (v1 / "memory.usage_in_bytes").write_text(f"{50 << 20}\n")
    (v1.parent / "memory.limit_in_bytes").write_text(f"{(1 << 63) - 4096}\n")  # v1's "no limit"
    (v1.parent / "memory.usage_in_bytes").write_text("0\n")
    assert system._cgroup_room(tmp_path / "v1", ["4:memory:/x", "0::/"]) == 450 << 20


def test_the_budget_follows_a_cgroup_lower_than_free_memory(tmp_path):
    """In a process whose cgroup allows 200 MB, available_memory() is at most 200 MB and a scene of 824 MB
    is refused by the default budget (3/4 of it) without --max-memory."""
    assert system.available_memory() > 1 << 30, "the test needs a machine with more than 1 GB free"
    cgroup = fake_cgroup(tmp_path / "cgroup", BUDGET)
    env = under_cgroup(cgroup)
    probe = "from raycast_phong.io.system import available_memory; print(available_memory())"
    done = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=60,
                          check=True)
    assert int(done.stdout) <= BUDGET
    (tmp_path / "big.toml").write_text('[[objects]]\nshape = "icosphere"\nsubdivisions = 8\n')
    done = subprocess.run([*CLI, "plan", "big.toml"], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2 and "above the 150 MB budget" in done.stderr, done.stderr


def textured_gltf(path: Path, png: bytes) -> Path:
    """One textured triangle whose base colour map is `png`: in the GLB's binary chunk for .glb, a base64
    `data:` URI for .gltf."""
    import base64
    import json
    geometry = struct.pack("<9f6f", 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1)
    document = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 24}]}
    if path.suffix == ".gltf":
        document["buffers"] = [{"byteLength": len(geometry), "uri": "data:application/octet-stream;base64,"
                                + base64.b64encode(geometry).decode()}]
        document["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(png).decode()}]
        path.write_text(json.dumps(document))
        return path
    binary = geometry + png + b"\0" * (-len(png) % 4)
    document["buffers"] = [{"byteLength": len(binary)}]
    document["bufferViews"].append({"buffer": 0, "byteOffset": len(geometry), "byteLength": len(png)})
    document["images"] = [{"bufferView": 2, "mimeType": "image/png"}]
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    chunks = (struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(binary), b"BIN\0") + binary)
    path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
    return path


HOSTILE_BUDGET = 300 << 20
LIMIT_300 = ["--max-memory", "300M"]


@pytest.fixture(scope="module")
def hostile_files(tmp_path_factory) -> Path:
    """Issue 30 item 3's inputs, each small on disk and each costing gigabytes if read as it claims: maps of
    12000² and 20000² (a scene's kd_map, an MTL's map_Kd, a GLB's image, a glTF `data:` image), a 3MF of
    47 MB of XML zipped small, a glTF whose accessors claim 3 vertices of a 2 GiB external buffer, a PLY face of
    3 M corners and a PLY strip of 10⁷ indices (headers: one element each), 10⁶ boxes in a 14 MB scene; and a
    fake cgroup of 300 MB over them all."""
    folder = tmp_path_factory.mktemp("hostile-300")
    claiming_png(folder / "map12k.png", 12000, 12000)
    claiming_png(folder / "map20k.png", 20000, 20000)
    (folder / "texture.toml").write_text(
        '[materials.m]\nkd_map = "map12k.png"\n[[objects]]\nshape = "plane"\nmaterial = "m"\n')
    (folder / "textured.mtl").write_text("newmtl m\nmap_Kd map20k.png\n")
    (folder / "textured.obj").write_text("mtllib textured.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                         "usemtl m\nf 1/1 2/2 3/3\n")
    textured_gltf(folder / "image.glb", (folder / "map20k.png").read_bytes())
    textured_gltf(folder / "image.gltf", (folder / "map20k.png").read_bytes())
    import numpy as np
    from test_file_guards import binary_ply, three_mf
    three_mf(folder / "bomb.3mf", 200_000)  # ≈ 47 MB of XML, ≈ 1.7 GB to parse
    with open(folder / "big.bin", "wb") as handle:
        handle.write(struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0))
        handle.truncate(2 << 30)
    import json
    (folder / "lie.gltf").write_text(json.dumps({
        "asset": {"version": "2.0"}, "buffers": [{"uri": "big.bin", "byteLength": 2 << 30}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "nodes": [{"mesh": 0}]}))
    binary_ply(folder / "corners.ply", 3, "face", [np.arange(3_000_000) % 3], count="int")
    binary_ply(folder / "strips.ply", 3, "tristrips", [np.arange(10_000_000) % 3], count="int")
    light = '[[lights]]\ntype = "point"\nposition = [0, 5, 5]\n'
    (folder / "boxes.toml").write_text("objects = [" + ",".join(['{shape="box"}'] * 1_000_000) + "]\n" + light)
    fake_cgroup(folder / "cgroup", HOSTILE_BUDGET)
    return folder


HOSTILE_RUNS = {  # input → a command line that reads it (the texture scene through every command that renders)
    "kd_map 12000²": ["render", "texture.toml", *LIMIT_300, "-o", "o.png"],
    "kd_map 12000², plan": ["plan", "texture.toml", *LIMIT_300],
    "kd_map 12000², side-by-side": ["side-by-side", "texture.toml", "--vary", "render.shading=flat,phong",
                                    *LIMIT_300, "-o", "s.png"],
    "kd_map 12000², study": ["study", "texture.toml", "--levels", "1", *LIMIT_300, "--out", "study"],
    "map_Kd 20000² (MTL)": ["render", "textured.obj", *LIMIT_300, "-o", "o.png"],
    "GLB image 20000²": ["render", "image.glb", *LIMIT_300, "-o", "o.png"],
    "glTF data: image 20000²": ["render", "image.gltf", *LIMIT_300, "-o", "o.png"],
    "3MF of 47 MB XML": ["render", "bomb.3mf", *LIMIT_300, "-o", "o.png"],
    "glTF claiming 3 vertices of 2 GiB": ["render", "lie.gltf", *LIMIT_300, "-o", "o.png"],
    "PLY face of 3M corners": ["plan", "corners.ply", *LIMIT_300],
    "PLY strip of 10⁷ indices": ["render", "strips.ply", *LIMIT_300, "-o", "o.png"],
    "10⁶ boxes": ["render", "boxes.toml", *LIMIT_300, "-o", "o.png"],
    "reference 16384²": ["reference", "--width", "16384", "--height", "16384", *LIMIT_300, "-o", "ref.exr"],
}


@pytest.mark.slow
@pytest.mark.parametrize("case", list(HOSTILE_RUNS))
def test_every_hostile_input_of_issue_30_stays_within_300M(case, hostile_files, baseline):
    """Each input is refused in one line (exit 2) or rendered (exit 0; a map shrunk as it is decoded), and the
    peak resident size stays within the 300 MB budget above the process's own (issue 30: before, 1.0–3.6 GB)."""
    code, peak, stderr = measured(HOSTILE_RUNS[case], hostile_files, hostile_files / "cgroup")
    assert "Traceback" not in stderr and "Warning" not in stderr, stderr
    assert code in (0, 2), (code, stderr)
    if code == 2:
        assert len([line for line in stderr.splitlines() if line.startswith("error")]) == 1, stderr
    assert peak <= baseline + HOSTILE_BUDGET, (f"{case}: peak {peak >> 20} MB, above the {HOSTILE_BUDGET >> 20} MB "
                                               f"budget over the process's own {baseline >> 20} MB")
