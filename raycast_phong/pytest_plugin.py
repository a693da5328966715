"""pytest plugin: compare rendered images with reference EXRs kept beside the test (docs/testing.md).

Registered through the `pytest11` entry point, so installing raycast-phong is enough:

    def test_sphere(assert_image_matches):
        image = raycast_phong.render_file("sphere.toml").image
        assert_image_matches(image, "sphere", atol=1e-3, fail_percent=0.2)

The reference is `references/sphere.exr` in the test file's folder, rewritten only under
`pytest --update-references`, which lists the files it wrote at the end of the session. On a failure the
actual and reference images (EXR, exact; PNG, to look at), the difference heat map and a side-by-side PNG are
written to the test's tmp_path, and the message gives the metrics and their paths.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

UPDATE_OPTION = "--update-references"
# The references written in this session, path → "new", "changed" or "unchanged" (the old file held the same
# float32 values); under xdist each worker hands its own to the controller (WORKER_OUTPUT), which prints them.
WRITTEN = pytest.StashKey[dict[str, str]]()
WORKER_OUTPUT = "raycast_phong_references_written"


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(UPDATE_OPTION, action="store_true", default=False,
                     help="raycast-phong: rewrite the reference images (references/<name>.exr beside each test) "
                          "from the current results; look at them before committing.")


def written_references(config: pytest.Config) -> dict[str, str]:
    """This session's record of the references written (WRITTEN), made on first use."""
    return config.stash.setdefault(WRITTEN, {})


def pytest_sessionfinish(session: pytest.Session) -> None:
    output = getattr(session.config, "workeroutput", None)  # set in an xdist worker only
    if output is not None:
        output[WORKER_OUTPUT] = written_references(session.config)


@pytest.hookimpl(optionalhook=True)  # xdist's hook: unknown, and never called, without it
def pytest_testnodedown(node, error) -> None:
    record = written_references(node.config)
    for path, status in getattr(node, "workeroutput", {}).get(WORKER_OUTPUT, {}).items():
        record.setdefault(path, status)


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:
    """Under --update-references, one line per reference written: new, changed or unchanged, and its path."""
    record = config.stash.get(WRITTEN, {})
    if not record:
        return
    counts = {status: sum(1 for s in record.values() if s == status) for status in ("new", "changed", "unchanged")}
    terminalreporter.write_sep("=", f"{len(record)} reference image{'s' * (len(record) != 1)} written ("
                               + ", ".join(f"{count} {status}" for status, count in counts.items() if count)
                               + "); look at them before committing")
    here = config.invocation_params.dir
    for path, status in sorted(record.items(), key=lambda item: (list(counts).index(item[1]), item[0])):
        shown = Path(path).relative_to(here) if Path(path).is_relative_to(here) else path
        terminalreporter.write_line(f"{status:<9} {shown}")


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
    """<name>-actual.exr, <name>-reference.exr (the exact float32 values) and (same size only) <name>-diff.png:
    the per-pixel largest difference as `compare --diff` draws it (tools.difference.difference_map), black 0 to
    pale yellow the largest; return the paths written."""
    folder.mkdir(parents=True, exist_ok=True)
    from .io.image_io import write_image
    from .tools.difference import difference_map
    written = [write_image(folder / f"{name}-actual.exr", np.ascontiguousarray(image, np.float32))]
    if reference is not None:
        written.append(write_image(folder / f"{name}-reference.exr", np.ascontiguousarray(reference, np.float32)))
    if reference is not None and match is not None and match.error is not None:
        written.append(write_image(folder / f"{name}-diff.png", difference_map(image, reference)))
    return written


@dataclass(frozen=True)
class SideBySide:
    """Where write_previews puts the three W×H panels "actual | reference | difference", in pixels (x to the
    right, y down). Font size f = io.labels.panel_font(H) (clamp(round(H / 10), 10, 32), as compare's), gap g =
    f // 2, label strip s = f + f // 2:

        y = g        the labels, height s, each over its panel
        y = g + s    the panels, height H, at x = g, 2g + W, 3g + 2W

    Size: width 3W + 4g, height H + s + 2g; io.labels.BACKDROP grey around the panels."""
    width: int   # W, one panel
    height: int  # H
    font: int    # f
    gap: int     # g
    strip: int   # s

    @classmethod
    def of(cls, width: int, height: int) -> SideBySide:
        from .io.labels import panel_font
        font = panel_font(height)
        return cls(width, height, font, font // 2, font + font // 2)

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the whole picture."""
        return 3 * self.width + 4 * self.gap, self.height + self.strip + 2 * self.gap

    def column(self, index: int) -> int:
        return self.gap + index * (self.width + self.gap)


def write_previews(folder: Path, name: str, image: np.ndarray, reference: np.ndarray | None) -> list[Path]:
    """8-bit PNGs that any viewer opens, with the values `render -o x.png` stores for render.colour "display"
    (clamped to [0, 1], no curve): <name>-actual.png, <name>-reference.png and (same size only)
    <name>-side-by-side.png, "actual | reference | difference" labelled (SideBySide; no labels without a font,
    image_io.label_font). Return the paths written, the side-by-side first."""
    folder.mkdir(parents=True, exist_ok=True)
    from .io.image_io import write_image
    written = [write_image(folder / f"{name}-actual.png", image)]
    if reference is None:
        return written
    written.append(write_image(folder / f"{name}-reference.png", reference))
    if np.shape(image) == np.shape(reference):
        written.insert(0, write_image(folder / f"{name}-side-by-side.png", side_by_side(image, reference)))
    return written


def side_by_side(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Two (H, W, 3) images of one size → the SideBySide picture, float32: actual, reference and their
    difference heat map (tools.difference.difference_map, as `compare --diff` writes it), each labelled as
    compare's panels are (io.labels: the longer wording where every label fits, else the shorter)."""
    from .io.labels import BACKDROP, draw_text, row_wording
    from .tools.difference import difference, difference_map
    grid = SideBySide.of(image.shape[1], image.shape[0])
    width, height = grid.size
    canvas = np.full((height, width, 3), BACKDROP, np.float32)
    with np.errstate(invalid="ignore"):
        error = difference(image, reference)
    finite = error[np.isfinite(error)]
    scale = f"difference, max {float(finite.max()):.3g}" if finite.size else "difference"
    top = grid.gap + grid.strip
    for index, panel in enumerate((image, reference, difference_map(image, reference))):
        canvas[top:top + grid.height, grid.column(index):grid.column(index) + grid.width] = panel
    texts, size = row_wording([("actual", "actual"), ("reference", "reference"), (scale, "difference")], grid.font,
                              grid.width)
    for index, text in enumerate(texts):  # without a font, nothing is drawn: the strips stay blank
        draw_text(canvas, text, (grid.column(index), grid.gap, grid.width, grid.strip), size)
    return canvas


class ReferenceImages:
    """The reference EXRs in one folder: compare against them, or rewrite them under --update-references
    (recording each in `written`, path → "new", "changed" or "unchanged")."""

    def __init__(self, folder: Path, update: bool, diagnostics: Path, written: dict[str, str] | None = None):
        self.folder, self.update, self.diagnostics = folder, update, diagnostics
        self.written = {} if written is None else written

    def load_or_update(self, name: str, image: np.ndarray) -> np.ndarray:
        """The reference `name` as (H, W, 3) float32; in update mode `image` is written first (and recorded in
        `written`).

        A missing reference fails the test (never passes silently) and says how to make one.
        """
        from .io.image_io import read_layer, write_image  # here: pytest loads this plugin in every session
        from .io.system import budget_of
        path = self.folder / f"{name}.exr"
        if self.update:
            before = self._old_values(path)
            try:
                self.folder.mkdir(parents=True, exist_ok=True)
                write_image(path, image)  # EXR: float32, zip-compressed, unclamped
            except OSError as error:  # a read-only folder, a full disk: one line, the old file as it was
                pytest.fail(f"{name}: cannot write the reference: {error}", pytrace=False)
            status = ("new" if before is None else
                      "unchanged" if np.array_equal(before, np.asarray(image, np.float32), equal_nan=True)
                      else "changed")
            self.written.setdefault(str(path.absolute()), status)
        elif not path.is_file():
            written = self._diagnose(name, image, None, None)
            pytest.fail(f"no reference image {path}; the result is in {', '.join(written)}; make the reference "
                        f"with `pytest {UPDATE_OPTION}`, look at it, and commit it", pytrace=False)
        # Read back even right after writing, so update runs also go through the EXR round trip. A reference is
        # the project's own file: the commands' budget, not the API's guard against a decompression bomb.
        return read_layer(path, max_memory=budget_of(None))

    @staticmethod
    def _old_values(path: Path) -> np.ndarray | None:
        """The values of the reference about to be replaced, or None if there is none (an unreadable one: empty,
        so it counts as changed)."""
        if not path.exists():
            return None
        from .io.image_io import read_layer
        from .io.system import budget_of
        try:
            return read_layer(path, max_memory=budget_of(None))
        except OSError:
            return np.empty(0, np.float32)

    def _diagnose(self, name: str, image: np.ndarray, reference: np.ndarray | None,
                  match: ImageMatch | None) -> list[str]:
        """Write the diagnostics and previews; the paths written, PNGs first, or why one could not be."""
        written: list[str] = []
        for write in (lambda: write_previews(self.diagnostics, name, image, reference),
                      lambda: write_diagnostics(self.diagnostics, name, image, reference, match)):
            try:
                written += map(str, write())
            except OSError as error:  # each file is written atomically: those before stay whole
                written.append(f"(not written: {error})")
        return sorted(written, key=lambda path: not path.endswith(".png"))  # stable: each part in its order

    def assert_matches(self, image: np.ndarray, name: str, *, rtol: float = 0.0, atol: float = 1e-3,
                       fail_percent: float = 0.0, edges: np.ndarray | None = None) -> ImageMatch:
        """Fail the test unless `image` matches references/<name>.exr (see match_images); return the match.

        The failure message is the metrics, then the path of each image written, one a line (write_previews,
        write_diagnostics)."""
        array = np.asarray(image)
        if array.ndim != 3 or array.shape[2] != 3 or 0 in array.shape or array.dtype.kind not in "biuf":
            pytest.fail(f"{name}: the image must be an (H, W, 3) array of real RGB values, as render() returns; "
                        f"got shape {array.shape}, dtype {array.dtype}", pytrace=False)
        reference = self.load_or_update(name, array)
        match = match_images(array, reference, rtol=rtol, atol=atol, fail_percent=fail_percent, edges=edges)
        if not match.passed:
            written = self._diagnose(name, array, reference, match)
            pytest.fail(f"{name}: {match.message}; written:\n" + "\n".join(f"  {path}" for path in written),
                        pytrace=False)
        return match


@pytest.fixture
def image_references(request: pytest.FixtureRequest, tmp_path: Path) -> ReferenceImages:
    """Reference images in the `references/` folder beside the requesting test module."""
    return ReferenceImages(Path(request.path).parent / "references",
                           update=request.config.getoption(UPDATE_OPTION), diagnostics=tmp_path,
                           written=written_references(request.config))


@pytest.fixture
def assert_image_matches(image_references: ReferenceImages) -> Callable[..., ImageMatch]:
    """assert_image_matches(image, name, rtol=0, atol=1e-3, fail_percent=0, edges=None): image (H, W, 3) against
    references/<name>.exr beside the test; see ReferenceImages.assert_matches."""
    return image_references.assert_matches
