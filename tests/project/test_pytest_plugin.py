"""The pytest plugin (raycast_phong/pytest_plugin.py) as a user's test suite meets it, through pytester."""

from __future__ import annotations

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


def written_paths(text: str) -> list[Path]:
    """The paths the first failure message lists, one a line, indented, after "written:".

    Only the first list: where the environment variable CI is set, pytest's short summary repeats the
    whole message, so the list appears twice.
    """
    lines = text.split("written:\n", 1)[1].splitlines()
    paths = []
    for line in lines:
        if not line.startswith("  /"):
            break
        paths.append(Path(line.strip()))
    return paths


def test_a_different_image_fails_with_metrics_and_its_images(pytester):
    write_test(pytester, 0.5)
    pytester.runpytest("--update-references").assert_outcomes(passed=1)
    write_test(pytester, 0.75)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    text = result.stdout.str()
    assert "square: 4.167% of pixels (1 of 24) are off by more than atol 0.001" in text
    assert "largest difference 0.25 at pixel (x 2, y 1)" in text
    paths = written_paths(text)
    assert [p.name for p in paths] == ["square-side-by-side.png", "square-actual.png", "square-reference.png",
                                       "square-diff.png", "square-actual.exr", "square-reference.exr"]
    assert all(p.is_file() for p in paths)
    assert rp.read_layer(paths[4])[1, 2, 0] == 0.75 and rp.read_layer(paths[5])[1, 2, 0] == 0.5
    # The reference is untouched by a failing run; fail_percent above the share lets it pass.
    assert rp.read_layer(pytester.path / "references" / "square.exr")[1, 2, 0] == 0.5
    write_test(pytester, 0.75, fail_percent=5)
    pytester.runpytest().assert_outcomes(passed=1)
    # --update-references rewrites it.
    write_test(pytester, 0.75)
    pytester.runpytest("--update-references").assert_outcomes(passed=1)
    assert rp.read_layer(pytester.path / "references" / "square.exr")[1, 2, 0] == 0.75


# A 32×24 image of values below 0, inside [0, 1] and above 1 (the PNGs clamp them), and its reference: the
# same with a 4×3 block raised by 0.25, so the difference has one scale.
PICTURE_TEST = """
import numpy as np

def picture(raised):
    image = np.random.default_rng(3).uniform(-0.2, 1.3, (24, 32, 3)).astype(np.float32)
    image[5:8, 10:14] += np.float32(0.25 * raised)
    return image

def test_picture(assert_image_matches):
    assert_image_matches(picture({raised}), "picture")
"""


def picture(raised: bool) -> np.ndarray:
    image = np.random.default_rng(3).uniform(-0.2, 1.3, (24, 32, 3)).astype(np.float32)
    image[5:8, 10:14] += np.float32(0.25 * raised)
    return image


def png_pixels(path: Path) -> np.ndarray:
    """An 8-bit RGB PNG's bytes as (H, W, 3) uint8, after checking its header says 8-bit RGB of that size."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR" and (data[24], data[25]) == (8, 2), path
    pixels, _ = rp.read_image(path)
    height, width = int.from_bytes(data[20:24], "big"), int.from_bytes(data[16:20], "big")
    assert pixels.shape == (height, width, 3)
    return np.round(pixels * 255).astype(np.uint8)  # read_image scales 8-bit values to [0, 1]


def test_a_failure_leaves_pngs_of_each_image_and_a_labelled_side_by_side(pytester, tmp_path):
    """The EXRs hold the exact values but few viewers open them: beside them, full-size 8-bit PNGs of the actual
    image, the reference and the difference (drawn as `compare --diff` draws it), and one picture
    "actual | reference | difference" with a label over each panel."""
    from raycast_phong.io.image_io import label_font
    from raycast_phong.tools.difference import difference_map
    pytester.makepyfile(test_user=PICTURE_TEST.format(raised=False))
    pytester.runpytest("--update-references").assert_outcomes(passed=1)
    pytester.makepyfile(test_user=PICTURE_TEST.format(raised=True))
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    paths = {p.name.removeprefix("picture-"): p for p in written_paths(result.stdout.str())}
    assert list(paths) == ["side-by-side.png", "actual.png", "reference.png", "diff.png", "actual.exr",
                           "reference.exr"]
    actual, reference = picture(True), picture(False)

    # The PNGs store the values as `render -o x.png` does for render.colour "display": clamped, no curve,
    # rounded, in the image's float32.
    def eight_bit(image):
        return np.round(np.clip(image, np.float32(0), np.float32(1)) * np.float32(255)).astype(np.uint8)
    np.testing.assert_array_equal(png_pixels(paths["actual.png"]), eight_bit(actual))
    np.testing.assert_array_equal(png_pixels(paths["reference.png"]), eight_bit(reference))
    assert not np.array_equal(eight_bit(actual), eight_bit(np.clip(actual, 0, 1) ** (1 / 2.2)))  # the control
    compare_diff = rp.write_image(tmp_path / "compare-diff.png", difference_map(actual, reference))
    np.testing.assert_array_equal(png_pixels(paths["diff.png"]), png_pixels(compare_diff))

    # Side by side: font 10 (its floor for H = 24), gap 5, label strip 15; 3 × 32 + 4 × 5 wide, 24 + 15 + 2 × 5
    # high. The panels are the three PNGs' pixels; grey around them, white label text above each.
    both = png_pixels(paths["side-by-side.png"])
    assert both.shape == (49, 116, 3)
    grey = round(0.18 * 255)
    for index, name in enumerate(["actual.png", "reference.png", "diff.png"]):
        x = 5 + index * 37
        np.testing.assert_array_equal(both[20:44, x:x + 32], png_pixels(paths[name]))
        assert (both[:, x - 5:x] == grey).all() and (both[:5, x:x + 32] == grey).all()
        assert label_font() is not None and both[5:20, x:x + 32].max() > 200, name  # a label's white text
    assert (both[:, -5:] == grey).all() and (both[-5:] == grey).all()


def test_a_side_by_side_without_a_font_keeps_its_size_and_blank_strips(monkeypatch):
    from raycast_phong.io import image_io
    from raycast_phong.pytest_plugin import side_by_side
    actual, reference = picture(True), picture(False)
    labelled = side_by_side(actual, reference)
    monkeypatch.setattr(image_io, "LABEL_FONTS", ("NoSuchFont",))
    blank = side_by_side(actual, reference)
    assert blank.shape == labelled.shape == (49, 116, 3)
    assert (blank[5:20] == np.float32(0.18)).all() and not (labelled[5:20] == np.float32(0.18)).all()
    np.testing.assert_array_equal(blank[20:], labelled[20:])


def test_update_references_lists_what_it_wrote(pytester):
    """At the end of an update run, one line per reference written (new, changed, unchanged) and the count;
    nothing in a run that writes none."""
    pytester.makepyfile(test_user=PICTURE_TEST.format(raised=False))
    quiet = pytester.runpytest()
    quiet.assert_outcomes(failed=1)  # no reference yet, and no update: nothing written, nothing said
    assert " written (" not in quiet.stdout.str()
    result = pytester.runpytest("--update-references")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*= 1 reference image written (1 new); look at them before committing =*",
                                 "new       references/picture.exr"])
    again = pytester.runpytest("--update-references")
    again.stdout.fnmatch_lines(["*= 1 reference image written (1 unchanged); *", "unchanged references/picture.exr"])
    pytester.makepyfile(test_user=PICTURE_TEST.format(raised=True))
    changed = pytester.runpytest("--update-references")
    changed.stdout.fnmatch_lines(["*= 1 reference image written (1 changed); *", "changed   references/picture.exr"])
    passing = pytester.runpytest()
    passing.assert_outcomes(passed=1)
    assert " written (" not in passing.stdout.str()


def test_update_references_lists_what_xdist_workers_wrote(pytester):
    """The project's own suite runs under xdist (-n auto): the workers write, the controller prints."""
    pytester.makepyfile(test_user=PICTURE_TEST.format(raised=False))
    result = pytester.runpytest("-n", "1", "--update-references")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*= 1 reference image written (1 new); *", "new       references/picture.exr"])


def test_an_image_of_the_wrong_shape_fails_in_one_line(pytester):
    pytester.makepyfile(test_user="""
import numpy as np

def test_grey(assert_image_matches):
    assert_image_matches(np.zeros((4, 6)), "grey")
""")
    for update in ([], ["--update-references"]):
        result = pytester.runpytest(*update)
        result.assert_outcomes(failed=1)
        result.stdout.fnmatch_lines(["grey: the image must be an (H, W, 3) array of real RGB values, as render() "
                                     "returns; got shape (4, 6), dtype float64"])
        assert "Error" not in result.stdout.str() and not (pytester.path / "references").exists()


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
