"""Every example scene in scenes/, rendered small, against its reference EXR in references/.

References are linear float32 EXRs, <scene>-<variant>.exr, rewritten only by `pytest --update-references`
(look at them before committing). Tolerances, with their reasons, are in tests/tolerances.py; the comparison
is the package's pytest plugin (assert_image_matches, docs/testing.md), which on a failure leaves the
render, the reference and a difference heat map in the test's tmp_path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.pytest_plugin import ImageMatch, match_images, write_diagnostics
from tolerances import IMAGE_TOLERANCES, STANDARD, ImageTolerance

SCENES = Path(__file__).resolve().parents[2] / "scenes"
TEST_WIDTH = 128  # 128×72 for a 16:9 scene: ~20 ms a render; references of 10–95 KB (smooth floors compress worst)

# What each variant changes in the scene as written.
VARIANT_OVERRIDES = {
    "authored": [],
    "flat": ["render.shading=flat"],
    "gouraud": ["render.shading=gouraud"],
    "phong": ["render.shading=phong"],
    "blinn": ["render.shading=phong", "render.specular=blinn"],
}


def render_small(scene_name: str, variant: str, extra: list[str] | tuple[str, ...] = ()) -> np.ndarray:
    """The scene at TEST_WIDTH pixels wide (its own aspect ratio), (H, W, 3) float32 linear RGB.

    Shading runs in float64, the house rule for references: what is compared is then the model, and
    float32 rounding (which differs across CPUs) stays far below the tolerance.
    """
    path = SCENES / f"{scene_name}.toml"
    authored = rp.load_scene(path)
    height = max(1, round(TEST_WIDTH * authored.render.height / authored.render.width))
    overrides = [f"render.width={TEST_WIDTH}", f"render.height={height}", "render.precision=float64",
                 *VARIANT_OVERRIDES[variant], *extra]
    return rp.render(rp.load_scene(path, overrides), source=str(path)).image


def assert_options(tolerance: ImageTolerance) -> dict[str, float]:
    """tests/tolerances.py's (pixel, share) as the plugin's keywords: atol = pixel, fail_percent = 100·share."""
    return {"rtol": 0.0, "atol": tolerance.pixel, "fail_percent": 100 * tolerance.share}


def compare_images(image: np.ndarray, reference: np.ndarray, tolerance: ImageTolerance) -> ImageMatch:
    """Count the pixels of `image` farther than tolerance.pixel from `reference` (both (H, W, 3))."""
    return match_images(image, reference, **assert_options(tolerance))


@pytest.mark.parametrize(("scene_name", "variant"), sorted(IMAGE_TOLERANCES),
                         ids=[f"{s}-{v}" for s, v in sorted(IMAGE_TOLERANCES)])
def test_render_matches_reference(scene_name, variant, assert_image_matches):
    image = render_small(scene_name, variant)
    assert_image_matches(image, f"{scene_name}-{variant}", **assert_options(IMAGE_TOLERANCES[scene_name, variant]))


def test_every_scene_has_a_reference_case():
    """A new example scene needs an entry in IMAGE_TOLERANCES (and a reference), not silence."""
    scenes = {path.stem for path in SCENES.glob("*.toml")}
    assert scenes == {scene for scene, _ in IMAGE_TOLERANCES}


def test_comparison_fails_on_a_changed_shininess(tmp_path):
    """The check can fail: the middle sphere's shininess 64 → 32 is caught, and diagnostics are written.

    Scratch run at 128×48: 43 pixels (0.70 %) change by more than 1e-3, 3.5× the 0.2 % allowed;
    even 64 → 63 moves 13 pixels (0.21 %), just over.
    """
    image = render_small("specular", "phong")
    # The reference goes through an EXR round trip, as a stored one does (read_layer's arrays are channel-planar).
    reference = rp.read_layer(rp.write_image(tmp_path / "unchanged.exr", image))
    changed = render_small("specular", "phong", ["materials.f64.shininess=32"])
    assert compare_images(image, reference, STANDARD).passed
    comparison = compare_images(changed, reference, STANDARD)
    assert not comparison.passed, comparison.message
    written = write_diagnostics(tmp_path, "specular-phong", changed, reference, comparison)
    assert [path.name for path in written] == ["specular-phong-actual.exr", "specular-phong-reference.exr",
                                               "specular-phong-diff.png"]
    np.testing.assert_array_equal(rp.read_layer(written[0]), changed.astype(np.float32))  # EXRs hold float32


def test_comparison_counts_nan_and_size_as_failures():
    reference = np.zeros((10, 10, 3), np.float32)
    broken = reference.copy()
    broken[0, 0:2] = np.nan  # 2 % of the pixels: above the 0.2 % allowed
    assert not compare_images(broken, reference, STANDARD).passed
    assert not compare_images(reference[:5], reference, STANDARD).passed


def test_comparison_allows_the_stated_share_of_outliers():
    tolerance = ImageTolerance(pixel=1e-3, share=0.01)
    reference = np.zeros((10, 10, 3), np.float32)
    one_off = reference.copy()
    one_off[3, 4, 1] = 0.5  # 1 pixel of 100: exactly the share allowed
    two_off = one_off.copy()
    two_off[5, 5, 0] = 2e-3
    assert compare_images(one_off, reference, tolerance).passed
    assert not compare_images(two_off, reference, tolerance).passed


def test_missing_reference_fails_with_a_hint(image_references, tmp_path):
    empty = type(image_references)(tmp_path / "references", update=False, diagnostics=tmp_path)
    with pytest.raises(pytest.fail.Exception, match="--update-references"):
        empty.load_or_update("nothing-here.exr", np.zeros((2, 2, 3), np.float32))
