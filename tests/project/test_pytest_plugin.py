"""The pytest plugin (raycast_phong/pytest_plugin.py) as a user's test suite meets it, through pytester."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp

# pytester's in-process runs drop the modules they imported when they end; OpenImageIO's native module
# aborts the process when imported a second time, so load it here, before the first run (run alone, this
# file used to die with SIGABRT on its second inner run).
import raycast_phong.io.image_io

USER_TEST = """
import numpy as np

def image(value):
    out = np.zeros((4, 6, 3), np.float32)
    out[1, 2] = value  # one pixel of 24 (4.2 %)
    return out

def test_matches(assert_image_matches):
    assert_image_matches(image({value}), "square", atol=1e-3, fail_percent={fail_percent})
"""


def write_test(pytester: pytest.Pytester, value: float, fail_percent: float = 0.0) -> None:
    pytester.makepyfile(test_user=USER_TEST.format(value=value, fail_percent=fail_percent))


def test_update_writes_the_reference_then_the_same_image_passes(pytester):
    write_test(pytester, 0.5)
    # Without a reference the test fails and says how to make one.
    missing = pytester.runpytest()
    missing.assert_outcomes(failed=1)
    missing.stdout.fnmatch_lines(["*no reference image*references/square.exr*--update-references*"])
    pytester.runpytest("--update-references").assert_outcomes(passed=1)
    reference = pytester.path / "references" / "square.exr"
    assert rp.read_layer(reference)[1, 2].tolist() == [0.5, 0.5, 0.5]
    pytester.runpytest().assert_outcomes(passed=1)


def test_a_different_image_fails_with_metrics_and_three_images(pytester):
    write_test(pytester, 0.5)
    pytester.runpytest("--update-references").assert_outcomes(passed=1)
    write_test(pytester, 0.75)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    text = result.stdout.str()
    assert "square: 4.167% of pixels (1 of 24) are off by more than atol 0.001" in text
    assert "largest difference 0.25 at pixel (x 2, y 1)" in text
    paths = [Path(p) for p in re.search(r"actual, reference, difference: (.*)", text)[1].split(", ")]
    assert [p.name for p in paths] == ["square-actual.exr", "square-reference.exr", "square-diff.png"]
    assert all(p.is_file() for p in paths)
    assert rp.read_layer(paths[0])[1, 2, 0] == 0.75 and rp.read_layer(paths[1])[1, 2, 0] == 0.5
    # The reference is untouched by a failing run; fail_percent above the share lets it pass.
    assert rp.read_layer(pytester.path / "references" / "square.exr")[1, 2, 0] == 0.5
    write_test(pytester, 0.75, fail_percent=5)
    pytester.runpytest().assert_outcomes(passed=1)
    # --update-references rewrites it.
    write_test(pytester, 0.75)
    pytester.runpytest("--update-references").assert_outcomes(passed=1)
    assert rp.read_layer(pytester.path / "references" / "square.exr")[1, 2, 0] == 0.75


def test_the_option_is_defined_once_by_the_plugin(pytester):
    result = pytester.runpytest("--help")
    assert result.stdout.str().count("--update-references") == 1


def test_on_edges_the_share_covers_only_values_the_neighbours_have():
    """match_images' `edges`: a pixel on an edge may take the other side's value, not any value, and an
    off pixel away from the edges always fails (the neighbourhood is the reference's own 3×3)."""
    from raycast_phong.pytest_plugin import match_images, neighbourhood_range
    reference = np.zeros((6, 6, 3))
    reference[:, 3:] = 1.0  # a vertical edge between columns 2 and 3
    edges = np.zeros((6, 6), bool)
    edges[:, 2:4] = True
    low, high = neighbourhood_range(reference)
    assert low.shape == high.shape == reference.shape
    assert (low[:, 2:4] == 0).all() and (high[:, 2:4] == 1).all() and (high[:, 0] == 0).all()

    def match(row, column, value):
        image = reference.copy()
        image[row, column] = value
        return match_images(image, reference, fail_percent=5, edges=edges)

    assert match(2, 3, 0.0).passed          # the other side's value, on the edge
    assert not match(2, 3, 2.0).passed      # on the edge, but no neighbour has it
    assert not match(2, 0, 1.0).passed      # a value the image has, but away from the edge
