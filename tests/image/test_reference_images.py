"""Every example scene in scenes/, rendered small, against its reference EXR in references/.

References are linear float32 EXRs, <scene>-<variant>.exr, rewritten only by `pytest --update-references`
(look at them before committing). Tolerances, with their reasons, are in tests/tolerances.py; the comparison
is the package's pytest plugin (assert_image_matches, docs/testing.md), which on a failure leaves the
render, the reference and a difference heat map in the test's tmp_path.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from tolerances import IMAGE_TOLERANCES, STANDARD, ImageTolerance

import raycast_phong as rp
import raycast_phong.scene.schema
from raycast_phong.geometry.build import build_geometry
from raycast_phong.pytest_plugin import ImageMatch, match_images, write_diagnostics

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


def small_scene(scene_name: str, variant: str, extra: list[str] | tuple[str, ...] = ()) -> rp.Scene:
    """The scene at TEST_WIDTH pixels wide (its own aspect ratio), in float64, with the variant's overrides.

    Shading runs in float64, the house rule for references: what is compared is then the model, and
    float32 rounding (which differs across CPUs) stays far below the tolerance.
    """
    path = SCENES / f"{scene_name}.toml"
    authored = rp.load_scene(path)
    height = max(1, round(TEST_WIDTH * authored.render.height / authored.render.width))
    overrides = [f"render.width={TEST_WIDTH}", f"render.height={height}", "render.precision=float64",
                 *VARIANT_OVERRIDES[variant], *extra]
    return rp.load_scene(path, overrides)


def render_small(scene_name: str, variant: str, extra: list[str] | tuple[str, ...] = ()) -> np.ndarray:
    """small_scene rendered: (H, W, 3) float64 linear RGB."""
    return rp.render(small_scene(scene_name, variant, extra)).image


def surface_keys(geometry) -> np.ndarray:
    """(F,) a label per face, equal for faces the shaded surface crosses without a jump: a flat face is its
    own surface; smooth faces sharing an edge with the same corner normals at both ends are one surface
    (a crease, a seam or another object starts a new one)."""
    faces, count = geometry.faces, len(geometry.faces)
    parent = np.arange(count)

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    smooth = geometry.face_model != 0
    if smooth.any():
        a, b = faces, np.roll(faces, -1, axis=1)                          # corner k → k + 1, (F, 3)
        na, nb = geometry.corner_normals, np.roll(geometry.corner_normals, -1, axis=1)
        swap = a > b                                                      # one orientation per edge
        lo, hi = np.where(swap, b, a).ravel(), np.where(swap, a, b).ravel()
        n_lo = np.where(swap[..., None], nb, na).reshape(-1, 3)
        n_hi = np.where(swap[..., None], na, nb).reshape(-1, 3)
        owner = np.repeat(np.arange(count), 3)
        order = np.lexsort((hi, lo))
        for i, j in itertools.pairwise(order):
            if lo[i] == lo[j] and hi[i] == hi[j] and smooth[owner[i]] and smooth[owner[j]] \
                    and np.allclose(n_lo[i], n_lo[j], atol=1e-9) and np.allclose(n_hi[i], n_hi[j], atol=1e-9):
                parent[root(owner[i])] = root(owner[j])
    return np.array([root(i) for i in range(count)])


def edge_pixels(scene: rp.Scene) -> np.ndarray:
    """(H, W) bool: pixels whose 3×3 neighbourhood meets more than one surface (surface_keys; the background is
    one more) or, in global mode, both sides of a shadow's edge: where a ray that Embree rounds differently
    can land on the other side of a jump. Found from a render of the face layer (and, in global mode, the
    difference from local mode, which is the shadows)."""
    from numpy.lib.stride_tricks import sliding_window_view

    def changes(labels):
        window = sliding_window_view(np.pad(labels, 1, mode="edge"), (3, 3))
        return window.min(axis=(-2, -1)) != window.max(axis=(-2, -1))

    with_face = scene.model_copy(update={"output": rp.scene.schema.Output(path="x.exr", aovs=("face",))})
    result = rp.render(with_face)
    face = result.aovs["face"][..., 0].astype(np.int64)
    keys = surface_keys(build_geometry(scene))
    edges = changes(np.where(face >= 0, keys[np.maximum(face, 0)], -1))
    if scene.render.mode == "global":
        local = rp.render(with_face.model_copy(update={"render": scene.render.model_copy(update={"mode": "local"})}))
        edges |= changes((np.abs(result.image - local.image).max(axis=2) > 1e-9).astype(np.int64))
    return edges


def assert_options(tolerance: ImageTolerance) -> dict[str, float]:
    """tests/tolerances.py's (pixel, share) as the plugin's keywords: atol = pixel, fail_percent = 100·share."""
    return {"rtol": 0.0, "atol": tolerance.pixel, "fail_percent": 100 * tolerance.share}


def compare_images(image: np.ndarray, reference: np.ndarray, tolerance: ImageTolerance,
                   edges: np.ndarray | None = None) -> ImageMatch:
    """Count the pixels of `image` farther than tolerance.pixel from `reference` (both (H, W, 3)); with
    `edges`, the share may be spent there only, within the neighbours' range (match_images)."""
    return match_images(image, reference, **assert_options(tolerance), edges=edges)


@pytest.mark.parametrize(("scene_name", "variant"), sorted(IMAGE_TOLERANCES),
                         ids=[f"{s}-{v}" for s, v in sorted(IMAGE_TOLERANCES)])
def test_render_matches_reference(scene_name, variant, assert_image_matches):
    """The render against references/<scene>-<variant>.exr, off pixels allowed only on edges (tolerances.py).

    How the references were made and checked: each was written by this renderer (`pytest tests/image
    --update-references`, float64 shading, 128 px wide) and looked at; none is an independent oracle. What
    ties them to the model: the specular scene's Phong render is checked against the analytic reference
    (its exact spheres) within a bound derived from the tessellation (test_analytic_images.py); the model
    itself by hand-computed pixels (tests/renderer/kernels/test_illumination.py, test_reference.py), cameras and
    layers by hand-built rays (test_camera_and_layers.py), shadows by analytic shadows (test_shadows.py).
    A reference is rewritten only with a commit that says why it changed.
    """
    scene = small_scene(scene_name, variant)
    image = rp.render(scene).image
    assert_image_matches(image, f"{scene_name}-{variant}", **assert_options(IMAGE_TOLERANCES[scene_name, variant]),
                         edges=edge_pixels(scene))


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


def test_comparison_fails_without_the_f512_highlight():
    """The share may not hide wrong pixels inside a surface: with k_s = 0 on the f = 512 sphere its whole
    highlight is gone, 4 pixels (up to 0.091 off) at 128×48, under the 18 the share allows, so a count alone
    passes it; none of them is on an edge, so the edge rule fails it."""
    scene = small_scene("specular", "phong")
    reference = rp.read_layer(Path(__file__).parent / "references" / "specular-phong.exr")
    edges = edge_pixels(scene)
    assert compare_images(rp.render(scene).image, reference, STANDARD, edges).passed
    dull = rp.render(small_scene("specular", "phong", ["materials.f512.ks=[0, 0, 0]"])).image
    count_only = compare_images(dull, reference, STANDARD)
    assert count_only.passed and 1 <= count_only.outliers.sum() <= 18, count_only.message
    with_edges = compare_images(dull, reference, STANDARD, edges)
    assert not with_edges.passed and with_edges.unexcused.sum() == count_only.outliers.sum(), with_edges.message
    assert "not on an edge" in with_edges.message


def test_edges_excuse_only_values_the_other_side_can_have():
    """On an edge pixel an off value inside the 3×3 neighbourhood's range is excused (a flip), one above it
    is not; off an edge nothing is, whatever the share."""
    reference = np.zeros((6, 6, 3))
    reference[:, 3:] = 0.5                                    # a vertical edge between columns 2 and 3
    edges = np.zeros((6, 6), bool)
    edges[:, 2:4] = True
    loose = ImageTolerance(pixel=1e-3, share=0.5)
    flipped = reference.copy()
    flipped[1, 2] = 0.5                                       # takes the other side's value: a flip
    assert compare_images(flipped, reference, loose, edges).passed
    brighter = reference.copy()
    brighter[1, 2] = 0.6                                      # brighter than either side
    assert not compare_images(brighter, reference, loose, edges).passed
    assert compare_images(brighter, reference, loose).passed  # the count alone lets it through
    inside = reference.copy()
    inside[1, 0] = 0.5                                        # the other side's value, but off the edge
    assert not compare_images(inside, reference, loose, edges).passed


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
