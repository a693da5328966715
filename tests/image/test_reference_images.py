"""Every example scene in scenes/, rendered small, against its reference EXR in references/.

References are linear float32 EXRs, <scene>-<variant>.exr, rewritten only by `pytest --update-references`
(look at them before committing). Tolerances, with their reasons, are in tests/tolerances.py. On a
failure the render, the reference and their difference are left in the test's tmp_path.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp
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


@dataclass(frozen=True, eq=False)
class Comparison:
    """A render against its reference under one tolerance."""
    error: np.ndarray | None     # (H, W) largest |render − reference| over R, G, B; None if the sizes differ
    outliers: np.ndarray | None  # (H, W) bool, error above tolerance.pixel (NaN counts as above)
    tolerance: ImageTolerance
    message: str                 # one line: how far off, and what is allowed

    @property
    def passed(self) -> bool:
        return self.outliers is not None and self.outliers.mean() <= self.tolerance.share


def compare_images(image: np.ndarray, reference: np.ndarray, tolerance: ImageTolerance) -> Comparison:
    """Count the pixels of `image` farther than tolerance.pixel from `reference` (both (H, W, 3))."""
    if image.shape != reference.shape:
        return Comparison(None, None, tolerance, f"size {image.shape} differs from the reference's {reference.shape}")
    error = np.abs(image.astype(np.float64) - reference.astype(np.float64)).max(axis=2)
    # `not <=` rather than `>`: a NaN pixel must count as wrong, not as equal.
    outliers = ~(error <= tolerance.pixel)
    worst = float(np.nanmax(error)) if not np.isnan(error).all() else float("nan")
    message = (f"{outliers.mean():.3%} of pixels ({int(outliers.sum())} of {outliers.size}) are off by more than "
               f"{tolerance.pixel:g} (allowed {tolerance.share:.2%}); largest difference {worst:.4g}"
               + (f", {int(np.isnan(error).sum())} NaN" if np.isnan(error).any() else ""))
    return Comparison(error, outliers, tolerance, message)


def save_comparison(folder: Path, stem: str, image: np.ndarray, reference: np.ndarray,
                    comparison: Comparison) -> list[Path]:
    """Write <stem>-render.exr, -reference.exr, and (same size only) -diff.exr (|render − reference|)
    and -outliers.png (the reference dimmed, pixels over tolerance in red); return their paths."""
    written = [rp.write_image(folder / f"{stem}-render.exr", image),
               rp.write_image(folder / f"{stem}-reference.exr", reference)]
    if comparison.outliers is not None:
        written.append(rp.write_image(folder / f"{stem}-diff.exr", np.abs(image - reference)))
        # Dimmed so the red marks stand out; contiguous because write_image(".png") cannot write the
        # channel-planar arrays read_layer returns.
        marked = np.ascontiguousarray(np.clip(reference, 0, 1) * 0.35)
        marked[comparison.outliers] = (1.0, 0.0, 0.0)
        written.append(rp.write_image(folder / f"{stem}-outliers.png", marked))
    return written


@pytest.mark.parametrize(("scene_name", "variant"), sorted(IMAGE_TOLERANCES),
                         ids=[f"{s}-{v}" for s, v in sorted(IMAGE_TOLERANCES)])
def test_render_matches_reference(scene_name, variant, references, tmp_path):
    image = render_small(scene_name, variant)
    reference = references.load_or_update(f"{scene_name}-{variant}.exr", image)
    comparison = compare_images(image, reference, IMAGE_TOLERANCES[scene_name, variant])
    if not comparison.passed:
        written = save_comparison(tmp_path, f"{scene_name}-{variant}", image, reference, comparison)
        pytest.fail(f"{scene_name}-{variant}: {comparison.message}; see {', '.join(map(str, written))}",
                    pytrace=False)


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
    written = save_comparison(tmp_path, "specular-phong", changed, reference, comparison)
    assert [path.name for path in written] == ["specular-phong-render.exr", "specular-phong-reference.exr",
                                               "specular-phong-diff.exr", "specular-phong-outliers.png"]
    np.testing.assert_allclose(rp.read_layer(written[2]), np.abs(changed - reference), atol=0)


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


def test_missing_reference_fails_with_a_hint(references, tmp_path):
    empty = type(references)(tmp_path / "references", update=False)
    with pytest.raises(pytest.fail.Exception, match="--update-references"):
        empty.load_or_update("nothing-here.exr", np.zeros((2, 2, 3), np.float32))
