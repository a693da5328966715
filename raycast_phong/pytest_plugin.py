"""pytest plugin: compare rendered images with reference EXRs kept beside the test (docs/testing.md).

Registered through the `pytest11` entry point, so installing raycast-phong is enough:

    def test_sphere(assert_image_matches):
        image = raycast_phong.render_file("sphere.toml").image
        assert_image_matches(image, "sphere", atol=1e-3, fail_percent=0.2)

The reference is `references/sphere.exr` in the test file's folder, rewritten only under
`pytest --update-references`. On a failure the actual, reference and difference images are written to the
test's tmp_path and the message gives their paths and the metrics.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

UPDATE_OPTION = "--update-references"


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(UPDATE_OPTION, action="store_true", default=False,
                     help="raycast-phong: rewrite the reference images (references/<name>.exr beside each test) "
                          "from the current results; look at them before committing.")


@dataclass(frozen=True, eq=False)
class ImageMatch:
    """An image against its reference: a pixel is off when a channel differs by more than atol + rtol·|reference|
    (NaN counts as off); the images match when at most fail_percent % of the pixels are off and none is
    unexcused (see match_images' `edges`)."""
    error: np.ndarray | None     # (H, W) largest |image − reference| over the channels; None if the sizes differ
    outliers: np.ndarray | None  # (H, W) bool, the pixels that are off
    fail_percent: float
    message: str                 # one line: how many pixels are off, allowed, the largest difference and where
    unexcused: np.ndarray | None = None  # (H, W) bool, off pixels the share may not cover (with `edges` only)

    @property
    def passed(self) -> bool:
        return (self.outliers is not None and int(self.outliers.sum()) <= self.fail_percent / 100 * self.outliers.size
                and (self.unexcused is None or not self.unexcused.any()))


def neighbourhood_range(reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel and channel, the smallest and largest reference value in its 3×3 neighbourhood."""
    from numpy.lib.stride_tricks import sliding_window_view
    padded = np.pad(reference, ((1, 1), (1, 1), (0, 0)), mode="edge")
    window = sliding_window_view(padded, (3, 3), axis=(0, 1))
    return window.min(axis=(-2, -1)), window.max(axis=(-2, -1))


def match_images(image: np.ndarray, reference: np.ndarray, *, rtol: float = 0.0, atol: float = 1e-3,
                 fail_percent: float = 0.0, edges: np.ndarray | None = None) -> ImageMatch:
    """Compare an (H, W, C) image with its (H, W, C) reference in float64.

    `edges` (H, W) bool, optional: the pixels an edge passes through (a silhouette, a flat facet's edge, a
    shadow's edge), where a ray rounded differently may land on the other side. Given it, the share
    fail_percent may be spent only there, and only on a value the other side can have: within the range of
    the reference's 3×3 neighbourhood (± atol + rtol·|reference|). Any other off pixel fails the match,
    so the share can no longer hide a few wrong pixels inside a surface (a missing highlight).
    """
    image, reference = np.asarray(image, np.float64), np.asarray(reference, np.float64)
    if image.shape != reference.shape:
        return ImageMatch(None, None, fail_percent,
                          f"size {image.shape} differs from the reference's {reference.shape}")
    difference = np.abs(image - reference)
    # `not <=` rather than `>`: a NaN must count as off, not as equal.
    outliers = ~(difference <= atol + rtol * np.abs(reference)).all(axis=2)
    error = difference.max(axis=2)
    finite = np.where(np.isnan(error), -np.inf, error)
    y, x = np.unravel_index(int(np.argmax(finite)), error.shape)
    nans = int(np.isnan(error).sum())
    unexcused = None
    if edges is not None:
        low, high = neighbourhood_range(reference)
        slack = atol + rtol * np.abs(reference)
        between = ((image >= low - slack) & (image <= high + slack)).all(axis=2)
        unexcused = outliers & ~(np.asarray(edges, bool) & between)
    message = (f"{outliers.mean():.3%} of pixels ({int(outliers.sum())} of {outliers.size}) are off by more than "
               f"atol {atol:g} + rtol {rtol:g}·|reference| (allowed {fail_percent:g}%"
               + (", on edges only, within the neighbours' range" if edges is not None else "")
               + f"); largest difference {finite[y, x]:.4g} at pixel (x {x}, y {y}); "
               + f"mean {float(np.nanmean(error)):.4g}"
               + (f"; {nans} NaN" if nans else ""))
    if unexcused is not None and unexcused.any():
        uy, ux = np.argwhere(unexcused)[0]
        message += (f"; {int(unexcused.sum())} off pixel(s) not on an edge or outside their neighbours' range, "
                    f"the first at (x {ux}, y {uy})")
    return ImageMatch(error, outliers, fail_percent, message, unexcused)


def write_diagnostics(folder: Path, name: str, image: np.ndarray, reference: np.ndarray | None,
                      match: ImageMatch | None) -> list[Path]:
    """<name>-actual.exr, <name>-reference.exr and (same size only) <name>-diff.png: the per-pixel largest
    difference as a heat map, black 0 to pale yellow the largest; return the paths written."""
    folder.mkdir(parents=True, exist_ok=True)
    from .io.image_io import write_image
    from .tools.difference import heat_map
    written = [write_image(folder / f"{name}-actual.exr", np.ascontiguousarray(image, np.float32))]
    if reference is not None:
        written.append(write_image(folder / f"{name}-reference.exr", np.ascontiguousarray(reference, np.float32)))
    if match is not None and match.error is not None:
        error = np.nan_to_num(match.error, nan=np.inf)
        scale = float(np.max(error[np.isfinite(error)], initial=0.0))
        written.append(write_image(folder / f"{name}-diff.png", heat_map(np.minimum(error, scale), scale)))
    return written


class ReferenceImages:
    """The reference EXRs in one folder: compare against them, or rewrite them under --update-references."""

    def __init__(self, folder: Path, update: bool, diagnostics: Path):
        self.folder = folder
        self.update = update
        self.diagnostics = diagnostics

    def path(self, name: str) -> Path:
        return self.folder / f"{name}.exr"

    def load_or_update(self, name: str, image: np.ndarray) -> np.ndarray:
        """The reference `name` as (H, W, 3) float32; in update mode `image` is written first.

        A missing reference fails the test (never passes silently) and says how to make one.
        """
        from .io.image_io import read_layer, write_image  # here: pytest loads this plugin in every session
        path = self.path(name)
        if self.update:
            self.folder.mkdir(parents=True, exist_ok=True)
            write_image(path, image)  # EXR: float32, zip-compressed, unclamped
        elif not path.is_file():
            written = write_diagnostics(self.diagnostics, name, image, None, None)
            pytest.fail(f"no reference image {path}; the result is in {written[0]}; make the reference with "
                        f"`pytest {UPDATE_OPTION}`, look at it, and commit it", pytrace=False)
        # Read back even right after writing, so update runs also go through the EXR round trip.
        return read_layer(path)

    def assert_matches(self, image: np.ndarray, name: str, *, rtol: float = 0.0, atol: float = 1e-3,
                       fail_percent: float = 0.0, edges: np.ndarray | None = None) -> ImageMatch:
        """Fail the test unless `image` matches references/<name>.exr (see match_images); return the match."""
        reference = self.load_or_update(name, image)
        match = match_images(image, reference, rtol=rtol, atol=atol, fail_percent=fail_percent, edges=edges)
        if not match.passed:
            written = write_diagnostics(self.diagnostics, name, image, reference, match)
            pytest.fail(f"{name}: {match.message}; actual, reference, difference: {', '.join(map(str, written))}",
                        pytrace=False)
        return match


@pytest.fixture
def image_references(request: pytest.FixtureRequest, tmp_path: Path) -> ReferenceImages:
    """Reference images in the `references/` folder beside the requesting test module."""
    return ReferenceImages(Path(request.path).parent / "references",
                           update=request.config.getoption(UPDATE_OPTION), diagnostics=tmp_path)


@pytest.fixture
def assert_image_matches(image_references: ReferenceImages) -> Callable[..., ImageMatch]:
    """assert_image_matches(image, name, rtol=0, atol=1e-3, fail_percent=0, edges=None): image (H, W, 3) against
    references/<name>.exr beside the test; see ReferenceImages.assert_matches."""
    return image_references.assert_matches
