"""Writes that fail must never look like success: a real file-size limit (RLIMIT_FSIZE) in a subprocess.

Each test first writes a good output without the limit (which also fills numba's cache, so the limited run
writes nothing else), then runs the real CLI again under a limit smaller than the new output, with SIGXFSZ
ignored so that write() fails with EFBIG instead of killing the process. The contract: exit non-zero, one
line naming the file and the OS reason, the old file byte for byte as it was, no temporary file left behind,
and a batch that records the scene as failed, never as rendered.
"""

from __future__ import annotations

import errno
import json
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import write_tiny_scene

import raycast_phong as rp

ROOT = Path(__file__).resolve().parents[2]
TOO_LARGE = os.strerror(errno.EFBIG)  # "File too large" in the C locale


def cli(*args: str | Path, limit: int | None = None) -> subprocess.CompletedProcess:
    """`python -m cli ARGS`, under a file-size limit of `limit` bytes if given."""
    def limited() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG from write(), not death by signal
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    env = {key: value for key, value in os.environ.items() if key != "RAYCAST_PHONG_DEBUG"}
    return subprocess.run([sys.executable, "-m", "raycast_phong.cli", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True,
                          timeout=300, env=env, preexec_fn=limited if limit is not None else None)


def assert_refused_write(done: subprocess.CompletedProcess, path: Path, code: int = 2) -> None:
    """Exit `code` with exactly one error line on stderr: PATH: write failed: File too large (the old file is
    unchanged). The scenes' own warnings and notes may come before it (a batch says them even under -q)."""
    assert done.returncode == code, (done.returncode, done.stdout, done.stderr)
    assert "Traceback" not in done.stderr
    lines = [line for line in done.stderr.splitlines() if not line.startswith(("warning: ", "note: "))]
    assert len(lines) == 1, done.stderr
    assert lines[0].endswith(f"{path}: write failed: {TOO_LARGE} (the old file is unchanged)"), lines[0]


def temporaries(folder: Path) -> list[str]:
    """Hidden files left in `folder`: temporaries (the batch's own lock file, .batch.lock, is not one)."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".") and p.name != ".batch.lock")


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    return write_tiny_scene(tmp_path, 64, 64)


@pytest.mark.parametrize("short", ["mid-write", "one byte"])
@pytest.mark.parametrize("suffix", [".png", ".exr"])
@pytest.mark.slow
def test_render_under_a_file_size_limit_keeps_the_old_image(scene, tmp_path, suffix, short):
    """Stopped mid-write, or one byte short: then only the writer's final flush at close fails, which
    OpenImageIO does not report (its open, write_image and close all return True)."""
    output = tmp_path / f"out{suffix}"
    assert cli("render", scene, "-o", output, "-q").returncode == 0
    old = output.read_bytes()
    assert len(old) > 1000
    bigger = ("--width", "256", "--height", "256")  # 16 times the pixels: well over 1000 bytes in either format
    limit = 1000
    if short == "one byte":  # the renderer is deterministic: the same command writes the same bytes
        probe = tmp_path / f"probe{suffix}"
        assert cli("render", scene, "-o", probe, *bigger, "-q").returncode == 0
        limit = probe.stat().st_size - 1
        probe.unlink()
    done = cli("render", scene, "-o", output, *bigger, limit=limit)
    assert_refused_write(done, output)
    assert done.stdout == ""  # no success line
    assert output.read_bytes() == old
    assert temporaries(tmp_path) == []


@pytest.mark.slow
def test_a_new_file_that_cannot_be_written_is_not_left_half_written(scene, tmp_path):
    cli("render", scene, "-o", tmp_path / "warm.png", "-q")
    output = tmp_path / "new.png"
    done = cli("render", scene, "-o", output, "--width", "256", "--height", "256", limit=1000)
    assert done.returncode == 2
    assert done.stderr.strip().endswith(f"{output}: write failed: {TOO_LARGE} (no file was written)")
    assert not output.exists() and temporaries(tmp_path) == []


def test_compare_diff_under_a_file_size_limit(tmp_path):
    rng = np.random.default_rng(7)
    a, b = (rp.write_image(tmp_path / name, rng.random((64, 64, 3), dtype=np.float32)) for name in ("a.png", "b.png"))
    diff = tmp_path / "diff.png"
    assert cli("compare", a, b, "--diff", diff).returncode == 1  # the images differ: exit 1, map written
    old = diff.read_bytes()
    assert len(old) > 4096  # a heat map of noise hardly compresses
    done = cli("compare", a, b, "--diff", diff, limit=4096)
    assert_refused_write(done, diff)
    assert "PASS" not in done.stdout and "FAILURE" not in done.stdout  # no verdict on a run that failed
    assert diff.read_bytes() == old and temporaries(tmp_path) == []


def test_side_by_side_under_a_file_size_limit(scene, tmp_path):
    output = tmp_path / "sbs.png"
    args = ("side-by-side", scene, "--vary", "render.shading=flat,phong", "-o", output, "--width", "32",
            "--height", "32")
    assert cli(*args).returncode == 0
    written = {path: path.read_bytes() for path in (output, tmp_path / "sbs-variants.exr")}
    assert all(len(data) > 2000 for data in written.values())
    done = cli(*args, limit=2000)
    assert_refused_write(done, tmp_path / "sbs-variants.exr")  # the first of the two files written
    assert {path: path.read_bytes() for path in written} == written
    assert temporaries(tmp_path) == []


@pytest.mark.slow
def test_reference_under_a_file_size_limit(scene, tmp_path):
    output = tmp_path / "ref.exr"
    assert cli("reference", scene, "-o", output).returncode == 0
    old = output.read_bytes()
    assert_refused_write(cli("reference", scene, "-o", output, limit=1000), output)
    assert output.read_bytes() == old and temporaries(tmp_path) == []


# The study writes study.csv (~500 bytes for one render), then error_vs_time.png (~28 kB), then summary.md:
# 200 bytes stops the CSV, 2000 the plot.
@pytest.mark.parametrize(("limit", "stopped"), [(200, "study.csv"), (2000, "error_vs_time.png")])
@pytest.mark.slow
def test_study_under_a_file_size_limit(scene, tmp_path, limit, stopped):
    out = tmp_path / "study"
    args = ("study", scene, "--levels", "0", "--models", "flat", "--repeats", "1", "--width", "16",
            "--height", "16", "--out", out)
    assert cli(*args).returncode == 0
    names = ("study.csv", "error_vs_time.png", "summary.md")
    before = {name: (out / name).read_bytes() for name in names}
    done = cli(*args, "--models", "flat,phong", limit=limit)  # two renders: a longer CSV
    assert_refused_write(done, out / stopped)
    assert (out / stopped).read_bytes() == before[stopped]
    assert (out / "summary.md").read_bytes() == before["summary.md"]  # written last, so never reached
    assert temporaries(out) == []


@pytest.mark.slow
def test_batch_records_an_image_it_could_not_write_as_failed(tmp_path):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    scene = write_tiny_scene(scenes, 128, 128)
    out = tmp_path / "out"
    assert cli("batch", scenes, "--out", out, "--jobs", "1", "-q").returncode == 0
    image = out / "tiny.png"
    old = image.read_bytes()
    assert len(old) > 2000
    scene.write_text(scene.read_text().replace("[0.9, 0.2, 0.2]", "[0.2, 0.9, 0.2]"))  # no longer up to date
    done = cli("batch", scenes, "--out", out, "--jobs", "1", "-q", limit=2000)
    assert done.returncode == 1, done.stderr  # a failed scene, as for any other scene that fails
    assert done.stderr.strip() == f"failed: {scene}: {image}: write failed: {TOO_LARGE} (the old file is unchanged)"
    assert image.read_bytes() == old and temporaries(out) == []
    entry = json.loads((out / "manifest.json").read_text())["scenes"]["tiny"]
    assert entry["status"] == "failed" and not entry.get("outputs")
    # Without the limit the scene renders again: a failed write never counts as up to date.
    again = cli("batch", scenes, "--out", out, "--jobs", "1")
    assert again.returncode == 0 and "1 rendered" in again.stdout, again.stdout
    assert image.read_bytes() != old


@pytest.mark.slow
def test_batch_manifest_under_a_file_size_limit(tmp_path):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    write_tiny_scene(scenes, 4, 4)
    out = tmp_path / "out"
    assert cli("batch", scenes, "--out", out, "--jobs", "1", "-q").returncode == 0
    manifest = out / "manifest.json"
    old = manifest.read_bytes()
    assert len(old) > 400 and (out / "tiny.png").stat().st_size < 400
    done = cli("batch", scenes, "--out", out, "--jobs", "1", "-q", "--force", limit=400)
    assert_refused_write(done, manifest)
    assert manifest.read_bytes() == old and temporaries(out) == []


@pytest.mark.slow
def test_batch_contact_sheet_under_a_file_size_limit(tmp_path):
    """Two 64×64 cells (~1-2 kB each) and the manifest (~2 kB) fit under 2500 bytes; their sheet (~3.5 kB) does not."""
    folder = tmp_path / "scenes"
    folder.mkdir()
    write_tiny_scene(folder, 64, 64)
    sweep = folder / "sweep.toml"
    sweep.write_text('scene = "tiny.toml"\n[grid]\nrender.shading = ["flat", "phong"]\n')
    out = tmp_path / "out"
    assert cli("batch", sweep, "--out", out, "--jobs", "1", "-q").returncode == 0
    sheet = out / "sweep-contact.png"
    old = sheet.read_bytes()
    assert len(old) > 2500 and (out / "manifest.json").stat().st_size < 2300
    done = cli("batch", sweep, "--out", out, "--jobs", "1", "-q", "--force", limit=2500)
    assert_refused_write(done, sheet)
    assert sheet.read_bytes() == old and temporaries(out) == []


def test_a_temporary_swapped_for_a_link_while_written_is_not_renamed_into_place(tmp_path):
    """In a folder others can write, the temporary file may be swapped for a link (or another file) between
    mkstemp and the rename: the write is refused, the old output and the link's target keep their bytes."""
    from raycast_phong.io.atomic import WriteError, replaced_atomically
    target, aimed, other = tmp_path / "out.txt", tmp_path / "precious", tmp_path / "other"
    target.write_bytes(b"old")
    aimed.write_bytes(b"keep me")
    refused = (r"out.txt: write failed: (Too many levels of symbolic links|the temporary file was replaced by "
               r"another file while it was written) \(the old file is unchanged\)")
    for swap in (lambda: other.symlink_to(aimed), lambda: other.write_bytes(b"someone else's")):
        with pytest.raises(WriteError, match=refused):
            with replaced_atomically(target, prefix=".out-") as temporary:
                swap()  # made while the temporary still exists: a new inode, then renamed over it
                other.replace(temporary)
        assert target.read_bytes() == b"old" and aimed.read_bytes() == b"keep me"
        assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt", "precious"]
