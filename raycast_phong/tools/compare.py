"""One scene rendered once per value of a key, composed into one labelled image, and measured.

parse_vary reads `KEY=V1,V2[,...]`; load_variants applies each value as `--set KEY=V` would; compose
lays the variants side by side over their difference heat maps (see Layout). The difference of two
(H, W, 3) linear images is, per pixel, the largest of |a − b| over R, G and B; every variant is measured
against the last. Pure numpy: image_io rasterises the label text.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SceneError
from ..io.image_io import label_font
from ..io.labels import BACKDROP, draw_text, fitting_size, panel_font, row_wording
from ..io.system import format_bytes
from ..scene.load import read_scene_dict
from ..scene.overrides import apply_override
from ..scene.schema import Scene, validate_scene
from ..values.messages import Location
from .difference import colour_map, difference, heat_map

# A pixel "changed" when its difference exceeds this: about 8 float32 steps at 1, so above rounding noise, and
# far below one 8-bit step (1/255), so every change a PNG could show is counted.
CHANGED_ABOVE = 1e-6

# ---------------------------------------------------------------- --vary


def split_top_level(text: str) -> list[str]:
    """`text` split on the commas outside brackets, braces and quotes: "[1,2],[3,4]" → ["[1,2]", "[3,4]"].

    Raises ValueError for a bracket closed before it opens, or one left open, or an unclosed quote.
    """
    items, depth, quote, start = [], 0, "", 0
    for index, char in enumerate(text):
        if quote:
            quote = "" if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
            if depth < 0:
                raise ValueError(f"{char!r} at character {index + 1} closes nothing")
        elif char == "," and depth == 0:
            items.append(text[start:index])
            start = index + 1
    if quote or depth:
        raise ValueError(f"an unclosed {quote or 'bracket'}")
    return [*items, text[start:]]


def parse_vary(text: str) -> tuple[str, list[str]]:
    """`KEY=V1,V2[,...]` as (key, [value text, ...]); at least two values, none empty.

    Raises SceneError with one line naming the key (or the whole text when there is no key).
    """
    key, _, values = (part.strip() for part in text.partition("="))
    if "=" not in text or not key:
        raise SceneError(f"--vary {text!r}: expected KEY.PATH=V1,V2[,...], e.g. render.shading=flat,gouraud,phong")
    try:
        items = [item.strip() for item in split_top_level(values)]
    except ValueError as error:
        raise SceneError(f"--vary {key}: cannot split {values!r} into values: {error}") from None
    if len(items) < 2:
        raise SceneError(f"--vary {key}: needs at least 2 values to compare, got {len(items)} ({values!r}); "
                         f"e.g. {key}={values or 'A'},B")
    empty = [str(index + 1) for index, item in enumerate(items) if not item]
    if empty:
        raise SceneError(f"--vary {key}: value {', '.join(empty)} of {len(items)} is empty in {values!r}")
    return key, items


def load_variants(path: str | Path, fixed: list[str], key: str, values: list[str], view: str | None = None,
                  up: str | None = None, max_memory: int | None = None) -> list[Scene]:
    """The scene file (or mesh file, framed from `view` with `up`) with the `fixed` overrides, then `key=value`
    for each value: one Scene per value.

    Every variant is validated before any is rendered; they must share one image size.
    """
    path = Path(path)
    data = read_scene_dict(path, fixed, view, up, max_memory)
    scenes = []
    for value in values:
        variant = copy.deepcopy(data)  # each value starts from the same file and --set overrides
        apply_override(variant, f"{key}={value}", source=str(path), option="--vary")
        scenes.append(validate_scene(variant, source=str(path), folder=path.parent))
    sizes = [(scene.render.width, scene.render.height) for scene in scenes]
    if len(set(sizes)) > 1:
        shown = ", ".join(f"{value} → {w}×{h}" for value, (w, h) in zip(values, sizes))
        raise SceneError(f"--vary {key}: the variants must share one image size to be compared; got {shown}",
                         Location(str(path)))
    return scenes


# ---------------------------------------------------------------- statistics


@dataclass(frozen=True)
class VariantStats:
    """One variant against the reference (the last variant)."""
    changed: float  # share of pixels whose difference exceeds CHANGED_ABOVE, in [0, 1]
    mean: float     # mean difference over all pixels
    max: float      # largest difference


def measure(diff: np.ndarray) -> VariantStats:
    """Share of changed pixels, mean and max of an (H, W) difference."""
    return VariantStats(changed=float((diff > CHANGED_ABOVE).mean()), mean=float(diff.mean()), max=float(diff.max()))


# ---------------------------------------------------------------- layout


@dataclass(frozen=True)
class Layout:
    """Where each part of the composed image sits, in pixels (x to the right, y down).

    For n panels of W×H: font size f = clamp(round(H / 10), 10, 32), gap g = f // 2, label strip
    s = f + f // 2, colour bar b = f. Column i (both rows) starts at x = g + i·(W + g). From the top:

        y = g                   top labels, height s         "key = value"
        y = g + s               the variants, height H       linear values (clamped only in a PNG)
        y = 2g + s + H          difference labels, height s  "value vs last", "last = reference"
        y = 2g + 2s + H         difference heat maps, height H
        y = 3g + 2s + 2H        colour bar, height b, from x = g to x = width − g
        y = 3g + 2s + 2H + b    its scale, height s: 0 at the left, the largest difference at the right

    Size: width n·W + (n + 1)·g, height 2H + 3s + b + 4g (g below the scale).
    """
    count: int   # n panels per row
    width: int   # W, one panel
    height: int  # H
    font: int    # f, label text size in pixels
    gap: int     # g
    strip: int   # s
    bar: int     # b

    @property
    def image_width(self) -> int:
        return self.count * self.width + (self.count + 1) * self.gap

    @property
    def image_height(self) -> int:
        return 2 * self.height + 3 * self.strip + self.bar + 4 * self.gap

    def column(self, index: int) -> int:
        """x of panel `index`'s left edge, in both rows."""
        return self.gap + index * (self.width + self.gap)

    @property
    def rows(self) -> dict[str, int]:
        """y of each band's top edge: labels, variants, difference_labels, differences, bar, scale."""
        g, s, h = self.gap, self.strip, self.height
        return {"labels": g, "variants": g + s, "difference_labels": 2 * g + s + h, "differences": 2 * g + 2 * s + h,
                "bar": 3 * g + 2 * s + 2 * h, "scale": 3 * g + 2 * s + 2 * h + self.bar}


def layout(count: int, width: int, height: int) -> Layout:
    """The Layout for `count` panels of width × height pixels."""
    font = panel_font(height)
    return Layout(count=count, width=width, height=height, font=font, gap=font // 2, strip=font + font // 2,
                  bar=font)


# ---------------------------------------------------------------- composition

@dataclass(frozen=True, eq=False)
class Comparison:
    """The composed image and what it shows."""
    image: np.ndarray              # (layout.image_height, layout.image_width, 3) float32
    layout: Layout
    variants: list[np.ndarray]     # the inputs, (H, W, 3) display values (io.encoding.display_values of each
                                   # render) float32 (float64 from float64 renders), in order
    differences: list[np.ndarray]  # per variant, (H, W) against the last, in the variants' precision
    stats: list[VariantStats]      # per variant, against the last (the last: all zero)
    scale: float                   # the largest difference: the colour bar's top
    labelled: bool                 # False when no font was found and the label strips are blank

    def parts(self) -> dict[str, tuple[np.ndarray, tuple[int, int]]]:
        """The variants as write_image parts: `variant0`, `variant1`, … each at its panel's (x, y)."""
        y = self.layout.rows["variants"]
        return {f"variant{index}": (variant, (self.layout.column(index), y))
                for index, variant in enumerate(self.variants)}


# Bytes per pixel of each variant while the variants are held and composed: its image (float32 RGB) and its
# difference, the heat map's temporary, its two panels on the canvas, and the canvas's copies when written
# (the 8-bit PNG's float32 RGB and the EXR of parts): 12 + 4 + 12 + 24 + 24 + 12, rounded up.
HELD_BYTES_PER_PIXEL = 96


def render_budget(scenes: list[Scene], budget: int | None) -> int | None:
    """What is left of `budget` for each variant's render once every variant's image is held and composed;
    SceneError (one line) when holding them alone is over it. None: no budget."""
    if budget is None:
        return None
    render = scenes[0].render
    held = len(scenes) * render.width * render.height * HELD_BYTES_PER_PIXEL
    if held >= budget:
        raise SceneError(f"--vary: {len(scenes)} variants of {render.width}×{render.height} pixels need "
                         f"≈ {format_bytes(held)} of memory to hold and compose, above the "
                         f"{format_bytes(budget)} budget; use fewer values, a smaller render.width × "
                         "render.height, or raise the budget (--max-memory)", scenes[0].origin)
    return budget - held


def compose(variants: list[np.ndarray], key: str, values: list[str]) -> Comparison:
    """Variants (each (H, W, 3) display values, float32 or float64, in the order of `values`: a render in
    render.colour = "linear" sRGB-encoded first, io.encoding.display_values) → the labelled Comparison."""
    height, width = variants[0].shape[:2]
    grid = layout(len(variants), width, height)
    rows = grid.rows
    differences = [difference(variant, variants[-1]) for variant in variants]
    scale = max(float(diff.max()) for diff in differences)
    canvas = np.full((grid.image_height, grid.image_width, 3), BACKDROP, np.float32)
    # Place each variant over its heat map.
    for index, (variant, diff) in enumerate(zip(variants, differences)):
        x = grid.column(index)
        canvas[rows["variants"]:rows["variants"] + height, x:x + width] = variant
        canvas[rows["differences"]:rows["differences"] + height, x:x + width] = heat_map(diff, scale)
    # The colour bar runs from 0 to `scale` across the panels' full span.
    left, right = grid.gap, grid.image_width - grid.gap
    ramp = (np.arange(right - left) + 0.5) / (right - left)  # pixel centres, so both ends sit inside [0, 1]
    canvas[rows["bar"]:rows["bar"] + grid.bar, left:right] = colour_map(ramp)
    labelled = _draw_labels(canvas, grid, key, values, scale)
    return Comparison(image=canvas, layout=grid, variants=list(variants), differences=differences,
                      stats=[measure(diff) for diff in differences], scale=scale, labelled=labelled)


def _draw_labels(canvas: np.ndarray, grid: Layout, key: str, values: list[str], scale: float) -> bool:
    """Write every label into its strip of the (image_height, image_width, 3) canvas; False if there is no font."""
    if label_font() is None:
        return False
    rows, reference = grid.rows, values[-1]
    # Each label has a full and a short wording: a row of narrow panels uses the short one throughout.
    above = [(f"{key} = {value}", value) for value in values]
    below = [(f"{value} vs {reference}", value) for value in values[:-1]] + [(f"{reference} = reference", "reference")]
    for row, wordings in (("labels", above), ("difference_labels", below)):
        texts, size = row_wording(wordings, grid.font, grid.width)
        for index, text in enumerate(texts):
            draw_text(canvas, text, (grid.column(index), rows[row], grid.width, grid.strip), size)
    # The scale: 0 at the left end, the top at the right, the caption centred between them if it fits.
    span, y = grid.image_width - 2 * grid.gap, rows["scale"]
    top = f"{scale:.3g}" if scale > 0 else "0 (no pixel differs)"
    zero = draw_text(canvas, "0", (grid.gap, y, span, grid.strip), grid.font)
    end = draw_text(canvas, top, (grid.gap, y, span, grid.strip), grid.font, align="right")
    room = span - zero - end - 2 * grid.font
    size = fitting_size(CAPTION, grid.font, room)
    if size is not None:
        draw_text(canvas, CAPTION, (grid.gap + zero + grid.font, y, room, grid.strip), size, align="center")
    return True


CAPTION = "max over RGB of |variant - reference|, linear"  # ASCII: the bundled font has no Δ or − glyph



