"""Hypothesis over hostile files and the environment (issue 21): mesh files whose headers claim anything, of
any size (sparse files), read through the header count, the size floor and the CLI; NUMBA_* values. The
contract: a count, or one SceneError line; the CLI exits 0 or 2 with one error line, within its budget.
"""

from __future__ import annotations

import os
import struct
import subprocess
import sys
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from raycast_phong.cli import app
from raycast_phong.errors import SceneError
from raycast_phong.io.meshes.source import mesh_source

runner = CliRunner()
CLI = [sys.executable, str(Path(__file__).parents[2] / "cli.py")]
counts = st.integers(0, 2**32 - 1)


@st.composite
def mesh_files(draw) -> tuple[str, bytes, int]:
    """(suffix, head, size): a header that claims a count, then a sparse tail to `size` bytes."""
    suffix = draw(st.sampled_from([".stl", ".ply", ".obj", ".off", ".gltf", ".glb"]))
    n, m = draw(counts), draw(counts)
    head = {
        ".stl": b"\0" * 80 + struct.pack("<I", n),
        ".ply": b"ply\nformat binary_little_endian 1.0\nelement vertex %d\nelement face %d\nend_header\n" % (m, n),
        ".obj": draw(st.sampled_from([b"v 0 0 0\n", b"f" + b" 1" * (n % 50), b"v 0 0 0 " * (m % 50)])),
        ".off": b"OFF\n%d %d 0\n" % (m, n),
        ".gltf": b'{"accessors": [{"count": %d}], "meshes": [{"primitives": [{"indices": 0}]}]}' % n,
        ".glb": b"glTF" + struct.pack("<III", 2, 0, n) + b"JSON",
    }[suffix]
    size = draw(st.sampled_from([len(head), len(head) + 1, 84 + 50 * (n % 1000), 1 << 20, 1 << 30]))
    return suffix, head, max(size, len(head))


def write(folder: Path, suffix: str, head: bytes, size: int) -> Path:
    path = folder / f"m{suffix}"
    with open(path, "wb") as handle:
        handle.write(head)
        handle.truncate(size)
    return path


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(file=mesh_files())
def test_a_hostile_mesh_header_gives_a_count_or_one_line(tmp_path, file):
    path = write(tmp_path, *file)
    try:
        count = mesh_source(path).triangles()
    except SceneError as error:
        assert "\n" not in str(error) and str(path) in str(error)
    else:
        assert isinstance(count, int) and count >= 0
    assert mesh_source(path).read_floor() >= path.stat().st_size


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(file=mesh_files())
def test_the_cli_on_a_hostile_mesh_is_0_or_one_line_2(tmp_path, file):
    path = write(tmp_path, *file)
    result = runner.invoke(app, ["plan", str(path), "--max-memory", "50M"])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 0 or (result.exit_code == 2 and len(lines) == 1), result.output[-2000:]


@settings(max_examples=12, deadline=None)
@given(name=st.sampled_from(["NUMBA_NUM_THREADS", "NUMBA_OPT", "NUMBA_DISABLE_JIT", "NUMBA_BOUNDSCHECK"]),
       value=st.sampled_from(["0", "-1", "abc", "", "1e9", "99999999999999999999", " 2 "]))
def test_any_numba_setting_is_run_or_refused_in_one_line(name, value):
    env = {k: v for k, v in os.environ.items() if k != "RAYCAST_PHONG_DEBUG"} | {name: value}
    done = subprocess.run([*CLI, "schema"], capture_output=True, text=True, timeout=120, env=env,
                          stdin=subprocess.DEVNULL)
    lines = done.stderr.strip().splitlines()
    assert "Traceback" not in done.stderr and len(lines) <= 1, done.stderr[-2000:]
    assert done.returncode in (0, 2) and (done.returncode == 0) == (not lines or lines[0].startswith("warning:"))
