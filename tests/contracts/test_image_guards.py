"""Every command that holds images keeps to the budget (issue 21, items 2 and 3): compare refuses images
whose headers claim more pixels than the budget holds before reading a pixel; side-by-side counts the
variants it holds; batch --jobs is capped by the cores and the budget and says so; a sweep of a million
cells is refused.
"""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

from typer.testing import CliRunner

from raycast_phong.cli import app

runner = CliRunner()
CLI = [sys.executable, str(Path(__file__).parents[2] / "cli.py")]


def claiming_png(path: Path, width: int, height: int) -> Path:
    """A real PNG of width × height black pixels that takes about 1/1000 of their bytes (zlib of zeros)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    data = zlib_of_zeros(height * (1 + 3 * width))  # each row: filter type 0, then its pixels
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", data) + chunk(b"IEND", b""))
    return path


def zlib_of_zeros(size: int) -> bytes:
    """A zlib stream of `size` zero bytes in milliseconds (deflating 1.2 GB for a 20000² PNG took 3.5 s of CPU): a
    megabyte of zeros deflated once at level 9 and ended by a full flush, so that each copy stands alone (no
    match reaches back into the one before), repeated; the remainder ends the stream; then the Adler-32 of n
    zeros, which is a = 1, b = n mod 65521 (RFC 1950)."""
    def deflated(count: int, mode: int) -> bytes:
        packer = zlib.compressobj(9, zlib.DEFLATED, -15)  # raw deflate: the zlib header and checksum are ours
        return packer.compress(bytes(count)) + packer.flush(mode)
    copies, rest = divmod(size, 1 << 20)
    return (b"\x78\xda" + deflated(1 << 20, zlib.Z_FULL_FLUSH) * copies + deflated(rest, zlib.Z_FINISH)
            + struct.pack(">I", (size % 65521) << 16 | 1))


def test_compare_refuses_images_whose_headers_claim_more_than_the_budget(tmp_path):
    """Two 200 kB PNGs of 8000 × 8000: before, compare held ≈ 3 GB of them (20000²: 16 GB, 85 s); now one line
    from the headers, in well under a second, within 400 MB."""
    a = claiming_png(tmp_path / "a.png", 8000, 8000)
    probe = ("import resource, subprocess, sys; done = subprocess.run(sys.argv[1:], capture_output=True, text=True);"
             " sys.stderr.write(done.stderr); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, "
             "done.returncode)")
    done = subprocess.run([sys.executable, "-c", probe, *CLI, "compare", str(a), str(a), "--max-memory", "100M"],
                          capture_output=True, text=True, timeout=300)
    peak, code = map(int, done.stdout.split())
    lines = done.stderr.strip().splitlines()
    assert code == 2 and len(lines) == 1, done.stderr
    assert "a.png: its header says 8000×8000 pixels with 3 channels" in lines[0] and "budget" in lines[0], lines[0]
    assert peak < 400 << 10, f"{peak >> 10} MB resident"


def test_compare_within_the_budget_still_compares(tmp_path):
    a = claiming_png(tmp_path / "a.png", 64, 64)
    result = runner.invoke(app, ["compare", str(a), str(a), "--max-memory", "100M"])
    assert result.exit_code == 0 and "PASS" in result.output, result.output


def test_side_by_side_counts_the_variants_it_holds(tmp_path):
    result = runner.invoke(app, ["side-by-side", "--vary", "render.shading=flat,phong,gouraud,flat,phong,gouraud",
                                 "--width", "4000", "--height", "4000", "--max-memory", "2G",
                                 "-o", str(tmp_path / "s.png")])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output
    assert "6 variants of 4000×4000 pixels need" in lines[0] and "2 GB budget" in lines[0], lines[0]
    assert not list(tmp_path.iterdir())


def test_batch_jobs_are_capped_by_the_cores_and_the_budget():
    from raycast_phong.tools.batch.run import WORKER_BYTES, worker_count
    cores = os.cpu_count() or 1
    count, warning = worker_count(cores + 38, None)
    assert count == cores and warning == f"--jobs {cores + 38}: {cores} worker{'s' * (cores != 1)} instead, as the " \
        f"machine has {cores} cores"
    assert worker_count(cores, None) == (cores, None)
    count, warning = worker_count(cores, 2 * WORKER_BYTES)  # room for one worker and its scenes
    assert count == 1 and (cores == 1 or "budget" in warning)


def test_each_batch_worker_is_given_room_for_itself_and_its_scenes(monkeypatch):
    """The budget holds budget // (2 × WORKER_BYTES) workers: each takes WORKER_BYTES before its first scene and
    its scenes as much again. On an 8-core machine, 4 × WORKER_BYTES runs 2 workers, a byte less 1. Catches the
    scenes' share left out (4 workers)."""
    from raycast_phong.tools.batch import run
    monkeypatch.setattr(run.os, "cpu_count", lambda: 8)
    assert run.worker_count(8, 4 * run.WORKER_BYTES)[0] == 2
    assert run.worker_count(8, 4 * run.WORKER_BYTES - 1)[0] == 1
    assert run.worker_count(2, 4 * run.WORKER_BYTES) == (2, None)  # as many as asked: no warning


def test_batch_says_when_the_cap_applies(tmp_path):
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "a.toml").write_text('[[objects]]\nshape = "box"\n[[lights]]\nposition = [2, 2, 3]\n'
                                   '[render]\nwidth = 8\nheight = 8\n')
    done = subprocess.run([*CLI, "batch", str(folder), "--out", str(tmp_path / "out"), "--jobs", "40", "-q"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "warning: --jobs 40: " in done.stderr, done.stderr


def test_a_sweep_of_a_million_cells_is_refused_at_once(tmp_path):
    (tmp_path / "base.toml").write_text('[[objects]]\nshape = "box"\n')
    values = ", ".join(str(i) for i in range(1000))
    (tmp_path / "sweep.toml").write_text(f'scene = "base.toml"\n[grid]\n"render.width" = [{values}]\n'
                                         f'"render.height" = [{values}]\n')
    result = runner.invoke(app, ["batch", str(tmp_path / "sweep.toml"), "--out", str(tmp_path / "out")])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output[:2000]
    assert "1,000 × 1,000 = 1,000,000 cells" in lines[0], lines[0]


def test_a_sweep_of_exactly_4096_cells_loads_and_one_more_cell_on_its_last_axis_is_refused(tmp_path):
    """MAX_SWEEP_CELLS is the most a sweep renders: 64 × 64 cells load (nothing is rendered by load_sweep), and a
    third axis of 2 × 2049 = 4098 past the limit only through its later axis is refused naming all three sizes.
    Catches `>` made `>=`, the limit moved by one, and a count of the first axis only."""
    import pytest

    from raycast_phong.errors import SceneError
    from raycast_phong.tools.sweep import MAX_SWEEP_CELLS, load_sweep
    (tmp_path / "base.toml").write_text('[[objects]]\nshape = "box"\n')

    def sweep(*sizes: int) -> Path:
        axes = ("render.width", "render.height", "camera.fov")
        grid = "".join(f'"{axis}" = [{", ".join(str(1 + i) for i in range(size))}]\n'
                       for axis, size in zip(axes, sizes))
        (tmp_path / "sweep.toml").write_text(f'scene = "base.toml"\n[grid]\n{grid}')
        return tmp_path / "sweep.toml"

    assert MAX_SWEEP_CELLS == 4096 and len(load_sweep(sweep(64, 64)).jobs()) == 4096
    with pytest.raises(SceneError, match=r"grid: 1 × 2 × 2,049 = 4,098 cells, more than the 4,096"):
        load_sweep(sweep(1, 2, 2049))
    with pytest.raises(SceneError, match=r"grid: 4,097 = 4,097 cells, more than the 4,096"):
        load_sweep(sweep(4097))


def test_a_truncated_png_in_compare_is_our_one_line_only(tmp_path):
    """libpng wrote its own `libpng error: …` line on stderr beside ours (issue 21, item 9)."""
    whole = tmp_path / "whole.png"
    done = subprocess.run([*CLI, "render", "-o", str(whole), "--width", "64", "--height", "64", "-q"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    cut = tmp_path / "cut.png"
    cut.write_bytes(whole.read_bytes()[:600])
    done = subprocess.run([*CLI, "compare", str(cut), str(whole)], capture_output=True, text=True, timeout=300)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and "libpng" not in done.stderr, done.stderr
    assert lines[0].startswith(f"error: {cut}: cannot read (") and "\\n" not in lines[0], lines[0]


def test_a_truncated_png_map_is_our_one_line_only(tmp_path):
    """Issue 30 item 10: a truncated PNG as a scene's kd_map printed libpng's own `libpng error: IDAT: Read
    error: …` line before ours (OpenImageIO's scanline reads let libpng's handler print on fd 2); now the read
    runs with fd 2 captured and given back without libpng's lines."""
    whole = tmp_path / "whole.png"
    done = subprocess.run([*CLI, "render", "-o", str(whole), "--width", "64", "--height", "64", "-q"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    (tmp_path / "cut.png").write_bytes(whole.read_bytes()[:600])
    scene = tmp_path / "s.toml"
    scene.write_text('[materials.m]\nkd_map = "cut.png"\n[[objects]]\nshape = "uv_sphere"\nmaterial = "m"\n')
    done = subprocess.run([*CLI, "render", str(scene), "-o", str(tmp_path / "o.png")], capture_output=True,
                          text=True, timeout=300)
    lines = [line for line in done.stderr.strip().splitlines() if not line.startswith("compiling")]
    assert done.returncode == 2 and len(lines) == 1 and "libpng" not in done.stderr, done.stderr
    assert lines[0].startswith(f"error: {scene}: materials.m.kd_map: '{tmp_path / 'cut.png'}' cannot be read as an "
                               "image"), lines


def test_what_else_a_block_prints_on_fd_2_is_given_back(capfd):
    """native_errors_kept drops only the native libraries' own error lines."""
    from raycast_phong.io.files import native_errors_kept
    with native_errors_kept():
        os.write(2, b"libpng error: IDAT: Read error\nsomething else\n")
    assert capfd.readouterr().err == "something else\n"


def test_srgb_with_an_exr_output_renders_in_linear_colour_and_its_header_says_so(tmp_path):
    """--srgb once warned it did nothing to an EXR; it now stands for render.colour = linear, which the EXR's
    values are in (unencoded, as before) and its header says."""
    from raycast_phong.io.image_io import image_colour
    result = runner.invoke(app, ["render", "-o", str(tmp_path / "x.exr"), "--srgb", "--width", "8", "--height", "8",
                                 "-q"])
    assert result.exit_code == 0, result.output
    # -q still prints the plan's warnings (an 8×8 image misses the highlight): none of them about --srgb
    assert not [line for line in result.output.splitlines() if "srgb" in line.lower() or ".exr" in line], \
        result.output
    assert image_colour(tmp_path / "x.exr") == "linear"


def test_a_contact_sheet_over_the_budget_is_refused_before_its_cells_are_read(tmp_path):
    """A sweep's nine 200×200 cells each render within --max-memory 12M (≈ 3 MB each), but the sheet that holds
    and composes them all needs ≈ 17 MB: one line, exit 2, after the cells and the manifest are written (before:
    the sheet was made whatever the budget)."""
    (tmp_path / "base.toml").write_text('[render]\nwidth = 200\nheight = 200\n[[objects]]\nshape = "box"\n')
    (tmp_path / "sweep.toml").write_text('scene = "base.toml"\n[grid]\n"render.shading" = ["flat", "gouraud", '
                                         '"phong"]\n"materials.default.shininess" = [1, 8, 64]\n')
    out = tmp_path / "out"
    result = runner.invoke(app, ["batch", str(tmp_path / "sweep.toml"), "--out", str(out), "--jobs", "1",
                                 "--max-memory", "12M", "-q"])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output[:2000]
    assert "sweep-contact.png: the contact sheet of 9 cells of up to 200×200 pixels" in lines[0], lines[0]
    assert "above the 12 MB budget" in lines[0], lines[0]
    assert len(list(out.glob("sweep--*.png"))) == 9 and not (out / "sweep-contact.png").exists()
    assert (out / "manifest.json").is_file()
    result = runner.invoke(app, ["batch", str(tmp_path / "sweep.toml"), "--out", str(out), "--jobs", "1", "-q"])
    assert result.exit_code == 0 and (out / "sweep-contact.png").is_file(), result.output


def test_a_sheet_whose_need_is_exactly_the_budget_is_made_and_one_byte_less_refused(tmp_path):
    """The sheet's need is every cell held (12 B a pixel), the composed sheet (28 B a pixel) and the largest cell
    as compare reads it (COMPARE_BYTES_PER_SAMPLE a sample): two RGB cells, one 300 × 200 and one 100 × 50, fit a
    budget of exactly that sum and not one byte less. Catches `>` made `>=` and a term left out."""
    import pytest

    from raycast_phong.errors import ImageError
    from raycast_phong.tools.sweep import COMPARE_BYTES_PER_SAMPLE, _sheet_grid, check_sheet_memory
    cells = [(("render.shading", value),) for value in ("flat", "phong")]
    outputs = [claiming_png(tmp_path / "0.png", 300, 200), claiming_png(tmp_path / "1.png", 100, 50)]
    grid, _ = _sheet_grid(cells, [(200, 300), (50, 100)])
    need = ((300 * 200 + 100 * 50) * 12 + grid.image_width * grid.image_height * 28
            + 300 * 200 * 3 * COMPARE_BYTES_PER_SAMPLE)
    check_sheet_memory(tmp_path / "s-contact.png", cells, outputs, need)
    with pytest.raises(ImageError, match=r"s-contact.png: the contact sheet of 2 cells of up to 300×200 pixels"):
        check_sheet_memory(tmp_path / "s-contact.png", cells, outputs, need - 1)


def test_the_sheet_check_reads_headers_only(tmp_path):
    """Cells whose headers claim 4000 × 4000 pixels (1 MB files): refused from the headers, naming the sheet."""
    import pytest

    from raycast_phong.errors import ImageError
    from raycast_phong.tools.sweep import check_sheet_memory
    cells = [(("render.shading", value),) for value in ("flat", "phong")]
    outputs = [claiming_png(tmp_path / f"{index}.png", 4000, 4000) for index in range(2)]
    with pytest.raises(ImageError, match=r"s-contact.png: the contact sheet of 2 cells of up to 4000×4000 pixels"):
        check_sheet_memory(tmp_path / "s-contact.png", cells, outputs, 500 << 20)
    check_sheet_memory(tmp_path / "s-contact.png", cells, outputs, 4 << 30)  # fits: no error


def test_reference_fine_is_refused_before_it_refines_over_the_budget(tmp_path):
    """`reference --fine 6` of the default scene makes three icospheres of subdivision 7 (983,040 triangles,
    ≈ 400 MB): with --max-memory 100M one line naming --fine and the budget, exit 2, before anything is refined; a
    mesh file of 1,280 triangles at --fine 6 would be Loop-subdivided to 5.2M before the render's own check."""
    result = runner.invoke(app, ["reference", "--fine", "6", "--max-memory", "100M", "-o", str(tmp_path / "r.exr")])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output
    assert "--fine 6: the refined scene has 983,040 triangles" in lines[0] and "above the 100 MB budget" in lines[0]
    import trimesh
    trimesh.creation.icosphere(3).export(tmp_path / "ball.ply")
    result = runner.invoke(app, ["reference", str(tmp_path / "ball.ply"), "--fine", "6", "--max-memory", "500M",
                                 "-o", str(tmp_path / "r.exr")])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output
    assert "--fine 6: the refined scene has 5.2M triangles" in lines[0], lines[0]
    assert not (tmp_path / "r.exr").exists()


def test_compare_refuses_a_fifo_or_a_device_at_once(tmp_path):
    """`compare a.png fifo.png` waited for ever inside OpenImageIO's open; a device read without end. Each is
    refused by its kind before any open, one line, exit 2 (a subprocess with a timeout: the old code hung)."""
    import numpy as np

    import raycast_phong as rp
    rp.write_image(tmp_path / "a.png", np.zeros((4, 4, 3), np.float32))
    os.mkfifo(tmp_path / "pipe.png")
    for other, kind in ((tmp_path / "pipe.png", "a named pipe (FIFO)"), (Path("/dev/zero"), "a device")):
        done = subprocess.run([*CLI, "compare", str(tmp_path / "a.png"), str(other)], capture_output=True, text=True,
                              timeout=120, stdin=subprocess.DEVNULL)
        assert done.returncode == 2, done.stderr
        assert done.stderr == f"error: {other}: is {kind}, not a regular file; give an image file (PNG, EXR, ...)\n"


def test_a_file_named_as_an_image_that_starts_as_none_is_refused_from_its_first_bytes(tmp_path):
    """A non-image named .png went to OpenImageIO, which tried every reader it has (over 90 s for 3 GiB): the
    format is decided from the first bytes, in one line; a misnamed image (a JPEG called .png) still reads."""
    import numpy as np

    import raycast_phong as rp
    rp.write_image(tmp_path / "a.png", np.zeros((4, 4, 3), np.float32))
    (tmp_path / "text.png").write_bytes(b"hello, not an image\n" * 1000)
    result = runner.invoke(app, ["compare", str(tmp_path / "a.png"), str(tmp_path / "text.png")])
    assert result.exit_code == 2
    assert result.stderr == (f"error: {tmp_path / 'text.png'}: not a PNG file: it starts with b'hello, n'; give an "
                             "image file (PNG, EXR, ...)\n")
    rp.write_image(tmp_path / "b.exr", np.zeros((4, 4, 3), np.float32))
    (tmp_path / "b.exr").rename(tmp_path / "exr-called.png")  # an image under another format's suffix
    assert runner.invoke(app, ["compare", str(tmp_path / "a.png"), str(tmp_path / "exr-called.png")]).exit_code == 0


def test_a_scene_map_that_is_no_image_is_refused_by_the_memory_check_before_any_reader_probes_it(tmp_path,
                                                                                                   monkeypatch):
    """A 3 GiB file of zeros named .png as a kd_map: OpenImageIO tried every reader on it in the memory estimate
    (over 90 s). It is refused from its first bytes when the estimate looks at it, before any compile or
    decode; a mesh file's map of that kind gets no size (its read notes it) without a reader opening it."""
    import OpenImageIO as oiio
    import pytest

    import raycast_phong as rp
    from raycast_phong.io.textures import file_size
    from raycast_phong.renderer.prepare import Renderer

    with open(tmp_path / "zeros.png", "wb") as handle:
        handle.truncate(64 << 20)  # sparse: no disk
    (tmp_path / "s.toml").write_text('[[objects]]\nshape = "icosphere"\nmaterial = "m"\n\n'
                                     '[materials.m]\nkd_map = "zeros.png"\n')

    probes = []
    monkeypatch.setattr(oiio.ImageInput, "open", lambda *arguments: probes.append(arguments))
    scene = rp.load_scene(tmp_path / "s.toml")
    with pytest.raises(rp.SceneError) as refused:
        Renderer().check_fits(scene)
    assert str(refused.value) == (f"{tmp_path / 's.toml'}: materials.m.kd_map: '{tmp_path / 'zeros.png'}' is not "
                                  "a PNG file: it starts with b'" + "\\x00" * 8 + "'; give a PNG, JPEG, EXR or "
                                  "another image file")
    assert file_size(tmp_path / "zeros.png") is None
    assert probes == []
