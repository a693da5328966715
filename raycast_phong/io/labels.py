"""White labels drawn into float images: compare's and side-by-side's panels, a sweep's contact sheet and the
pytest plugin's failure picture. The grey behind the panels, the size a label fits at, and the blend; the glyphs
are io.image_io.text_coverage's. No scene, no renderer."""

from __future__ import annotations

import numpy as np

from .image_io import text_coverage

BACKDROP = 0.18  # mid-dark grey behind the panels: their black backgrounds keep a visible edge, white text reads
TEXT_RGB = (1.0, 1.0, 1.0)
MIN_FONT = 8     # labels shrink to fit down to this size; below it they are cut at the panel's edge


def panel_font(height: int) -> int:
    """The labels' font size over panels `height` pixels tall: a tenth of it, at least 10 (the smallest that
    stays legible), at most 32 (plenty). Their gaps are half of it, their strips one and a half."""
    return min(max(round(height / 10), 10), 32)


def row_wording(wordings: list[tuple[str, ...]], size: int, width: int) -> tuple[list[str], int]:
    """One row's labels: the first wording that fits every label in `width` at MIN_FONT or larger, and the
    largest size up to `size` at which all of them fit; if none fits, the last wording at MIN_FONT."""
    for choice in range(len(wordings[0])):
        sizes = [fitting_size(wording[choice], size, width) for wording in wordings]
        if None not in sizes:
            return [wording[choice] for wording in wordings], min(sizes)
    return [wording[-1] for wording in wordings], MIN_FONT


def fitting_size(text: str, size: int, width: int) -> int | None:
    """The largest font size from `size` down to MIN_FONT at which `text` is at most `width` wide, or None."""
    while size >= MIN_FONT:
        drawn = text_coverage(text, size)
        if drawn is None or drawn.shape[1] <= width:
            return size if drawn is not None else None
        # Text width grows about linearly with the size: jump to near the fit, then step down.
        size = min(size - 1, size * width // drawn.shape[1])
    return None


def draw_text(canvas: np.ndarray, text: str, box: tuple[int, int, int, int], size: int,
               align: str = "left") -> int:
    """Blend one line of white text into box = (x, y, width, height) of the canvas, centred vertically and cut
    at the box's edges. Returns the width drawn in pixels (0 without a font)."""
    x, y, width, height = box
    coverage = text_coverage(text, size)
    if coverage is None or width <= 0:
        return 0
    h, w = min(coverage.shape[0], height), min(coverage.shape[1], width)
    left = x + {"left": 0, "center": (width - w) // 2, "right": width - w}[align]
    top = y + (height - h) // 2
    alpha = coverage[:h, :w, None]
    region = canvas[top:top + h, left:left + w]
    region[:] = region * (1 - alpha) + np.asarray(TEXT_RGB, np.float32) * alpha
    return w
