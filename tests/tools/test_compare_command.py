"""`raycast-phong compare A B`: OpenImageIO's metrics, idiff-style thresholds and exit status, the heat map."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app
from raycast_phong.io.image_io import compare_files

runner = CliRunner()


@pytest.fixture
def pair(tmp_path):
    """Two identical 8×6 EXRs (a ramp) and a path for a third."""
    image = np.linspace(0, 1, 8 * 6 * 3, dtype=np.float32).reshape(6, 8, 3)
    return image, rp.write_image(tmp_path / "a.exr", image), rp.write_image(tmp_path / "b.exr", image)


def test_identical_images_pass(pair):
    _, a, b = pair
    result = runner.invoke(app, ["compare", str(a), str(b)])
    assert result.exit_code == 0, result.output
    assert "PSNR inf dB, max error 0" in result.stdout and "PASS: 0 of 48 pixels" in result.stdout


def test_a_changed_pixel_beyond_the_threshold_fails_with_its_location(pair, tmp_path):
    image, a, _ = pair
    changed = image.copy()
    changed[4, 5, 2] += 0.25  # row 4 = y, column 5 = x, blue
    b = rp.write_image(tmp_path / "changed.exr", changed)
    diff = tmp_path / "diff.png"
    result = runner.invoke(app, ["compare", str(a), str(b), "--fail", "0.1", "--diff", str(diff)])
    assert result.exit_code == 1
    assert "max error 0.25 at pixel (5, 4) channel 2" in result.stdout
    assert "FAILURE: 1 of 48 pixels (2.08%) over --fail 0.1" in result.stdout
    heat = rp.read_image(diff)[0]
    assert heat.shape == (6, 8, 3)
    assert np.argmax(heat.sum(axis=2)) == 4 * 8 + 5  # the brightest heat-map pixel is the changed one
    # Within the threshold, or within --fail-percent, it passes (with a warning: above the 1e-6 warn default).
    assert runner.invoke(app, ["compare", str(a), str(b), "--fail", "0.3"]).stdout.startswith("mean error")
    assert runner.invoke(app, ["compare", str(a), str(b), "--fail", "0.3"]).exit_code == 0
    relaxed = runner.invoke(app, ["compare", str(a), str(b), "--fail", "0.1", "--fail-percent", "5"])
    assert relaxed.exit_code == 0 and "WARNING: 1 of 48" in relaxed.stdout


def test_metrics_are_openimageio_s(pair, tmp_path):
    image, a, _ = pair
    changed = image.copy()
    changed[0, 0] += 0.5
    found = compare_files(a, rp.write_image(tmp_path / "c.exr", changed), fail=0.1, warn=0.01)
    assert found.max == pytest.approx(0.5) and found.max_at == (0, 0)
    assert found.mean == pytest.approx(0.5 * 3 / image.size)
    assert found.rms == pytest.approx(np.sqrt(0.25 * 3 / image.size))
    assert (found.failed, found.warned, found.pixels) == (1, 1, 48)


def test_different_sizes_or_an_unreadable_file_exit_2(pair, tmp_path):
    image, a, _ = pair
    small = rp.write_image(tmp_path / "small.exr", image[:3])
    result = runner.invoke(app, ["compare", str(a), str(small)])
    assert result.exit_code == 2
    assert result.stderr.strip() == (f"error: {small}: 8×3 with 3 channels, but {a} is 8×6 with 3; only images "
                                     "of one size and channel count can be compared")
    missing = runner.invoke(app, ["compare", str(a), str(tmp_path / "missing.png")])
    assert missing.exit_code == 2 and missing.stderr.strip() == f"error: {tmp_path / 'missing.png'}: no such file"
