"""Sweeps: one base scene and a grid of overrides, rendered as their product, and a labelled contact sheet.

A sweep file is TOML with the base `scene` (relative to the sweep file), optional fixed overrides `set`,
and a `[grid]` table whose every leaf is a list of values for that key path (docs/batch.md):

    scene = "specular.toml"
    set = ["render.width=160"]
    [grid]
    render.shading = ["flat", "gouraud", "phong"]
    materials.f64.shininess = [8, 64]

Each cell of the product is a batch Job named `<sweep>--<label>=<value>--…`. The contact sheet puts the
last axis along the columns and the product of the others down the rows, in the grid's order.
"""

from __future__ import annotations

import itertools
import json
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ImageError, SceneError
from ..io.encoding import DISPLAY, display_values
from ..io.image_io import (
    COMPARE_BYTES_PER_SAMPLE,
    image_colour,
    image_header,
    read_layer,
    text_coverage,
    write_image,
)
from ..io.labels import BACKDROP, MIN_FONT, draw_text, fitting_size, row_wording
from ..io.scene_toml import toml_value
from ..io.system import budget_of, format_bytes
from ..values.messages import Location
from .compare import layout

SWEEP_KEYS = ("scene", "set", "grid")
# A sweep's product is rendered and shown on one sheet: a million cells would run for hours without a word.
MAX_SWEEP_CELLS = 4096
FAILED_RGB = (0.35, 0.06, 0.06)  # a failed cell: dark red, so it cannot pass for a black render
# A contact sheet's memory: every cell held as float32 RGB (12 B a pixel) until the sheet is composed, the
# sheet itself (12 B) and what writing it as an 8-bit PNG copies (16 B), and the cell being read
# (COMPARE_BYTES_PER_SAMPLE a channel, as compare reads).
CELL_BYTES_PER_PIXEL = 12
SHEET_BYTES_PER_PIXEL = 28
ROW_LABEL_MIN = 240  # px: room for "shading=gouraud, shininess=512" at 12 px, however small the cells


@dataclass(frozen=True)
class Job:
    """One image to make: a scene file, with overrides (a sweep's parameters), named for its output."""
    name: str                          # output file stem, unique within a batch
    scene: Path                        # the scene file
    overrides: tuple[str, ...] = ()    # `key.path=value`, applied as --set
    sweep: str | None = None           # the sweep file's stem, when the job is one cell of a sweep
    cell: tuple[tuple[str, str], ...] = ()  # the sweep's (label, value) per axis, in the grid's order


@dataclass(frozen=True)
class Sweep:
    """A parsed sweep file."""
    path: Path
    scene: Path                                  # the base scene file
    fixed: tuple[str, ...]                       # overrides applied to every cell
    axes: tuple[tuple[str, tuple[Any, ...]], ...]  # (key path, values) in the file's order

    @property
    def name(self) -> str:
        return self.path.stem

    def labels(self) -> list[str]:
        """Each axis's short name: the key's last part, or the whole path where two axes share a last part."""
        last = [key.rsplit(".", 1)[-1] for key, _ in self.axes]
        return [part if last.count(part) == 1 else key for part, (key, _) in zip(last, self.axes)]

    def jobs(self) -> list[Job]:
        """The product of the axes as batch Jobs, the last axis varying fastest."""
        labels = self.labels()
        jobs = []
        for values in itertools.product(*(values for _, values in self.axes)):
            texts = [toml_value(value) for value in values]
            cell = tuple((label, slug(text)) for label, text in zip(labels, texts))
            name = "--".join([self.name, *(f"{label}={value}" for label, value in cell)])
            overrides = (*self.fixed, *(f"{key}={text}" for (key, _), text in zip(self.axes, texts)))
            jobs.append(Job(name=name, scene=self.scene, overrides=overrides, sweep=self.name, cell=cell))
        return jobs


def is_sweep(path: Path) -> bool:
    """A TOML file with a top-level `grid` table (a scene file never has one)."""
    if path.suffix.lower() != ".toml" or not path.is_file():  # a FIFO would block the read: the loader refuses it
        return False
    try:
        return "grid" in tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):  # TOMLDecodeError, UnicodeDecodeError; nested too deep
        return False  # the scene loader reports the file's problem


def load_sweep(path: str | Path) -> Sweep:
    """Read and check a sweep file; every problem is one SceneError naming the file and the key."""
    path = Path(path)
    where = Location(str(path))
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as error:
        raise SceneError(f"cannot read the sweep file ({error})", where) from None
    except tomllib.TOMLDecodeError as error:
        raise SceneError(f"TOML syntax error: {error}", where) from None
    unknown = [key for key in data if key not in SWEEP_KEYS]
    if unknown:
        raise SceneError(f"unknown key; a sweep file has {', '.join(SWEEP_KEYS)}", where.at(unknown[0]))
    if not isinstance(data.get("scene"), str):
        raise SceneError("must be the base scene file, a string relative to the sweep file", where.at("scene"))
    fixed = data.get("set", [])
    if not isinstance(fixed, list) or not all(isinstance(item, str) and "=" in item for item in fixed):
        raise SceneError('must be a list of "key.path=value" strings, e.g. ["render.width=160"]', where.at("set"))
    if not isinstance(data.get("grid"), dict) or not data["grid"]:
        raise SceneError('must be a table of key paths and value lists, e.g. render.shading = ["flat", "phong"]',
                         where.at("grid"))
    axes = []
    for key, values in _leaves(data["grid"]):
        if not isinstance(values, list) or not values:
            raise SceneError(f"must be a non-empty list of values, got {json.dumps(values)}",
                             where.at("grid", *key.split(".")))
        axes.append((key, tuple(values)))
    cells = math.prod(len(values) for _, values in axes)
    if cells > MAX_SWEEP_CELLS:
        sizes = " × ".join(f"{len(values):,}" for _, values in axes)
        raise SceneError(f"{sizes} = {cells:,} cells, more than the {MAX_SWEEP_CELLS:,} a sweep renders (each is a "
                         "render and a cell of the contact sheet); split the sweep or use fewer values",
                         where.at("grid"))
    return Sweep(path=path, scene=_base_scene(path.parent, data["scene"]), fixed=tuple(fixed), axes=tuple(axes))


def _base_scene(folder: Path, name: str) -> Path:
    """The base scene a sweep names, relative to the sweep's folder, said as the user would say it: without `..`
    steps (docs/figures/../../scenes/x.toml is scenes/x.toml), relative to the working folder when it is below it,
    else absolute; `..` is taken on the real path (symbolic links followed), as the file system takes it."""
    joined = folder / name
    if ".." not in joined.parts:
        return joined
    real = joined.resolve()
    try:
        return real.relative_to(Path.cwd())
    except ValueError:
        return real


def _leaves(table: dict, prefix: str = "") -> list[tuple[str, Any]]:
    """A nested TOML table (dotted keys make tables) flattened back into (key path, value) pairs."""
    out = []
    for key, value in table.items():
        if isinstance(value, dict):
            out += _leaves(value, f"{prefix}{key}.")
        else:
            out.append((f"{prefix}{key}", value))
    return out


def slug(text: str) -> str:
    """A value's TOML text made safe for a file name: brackets, quotes and blanks dropped, others → '-'."""
    text = re.sub(r"[\[\]\"' ]", "", text)
    return re.sub(r"[^A-Za-z0-9._,+=-]", "-", text) or "empty"


# ---------------------------------------------------------------- contact sheet


@dataclass(frozen=True)
class SheetLayout:
    """Where each cell of a contact sheet sits, in pixels (x to the right, y down).

    Cells of W×H; gap g and label strip s from compare.layout (font f = clamp(round(H / 10), 10, 32),
    g = f // 2, s = f + f // 2); L the widest row label (0 for a single row). Column labels sit in the
    strip at y = g; cell (r, c) at x = x0 + c·(W + g), y = g + s + r·(H + g), with x0 = g (+ L + g with
    row labels, which sit at x = g). Size: x0 + C·(W + g) wide, g + s + R·(H + g) high.
    """
    rows: int
    columns: int
    width: int        # W, one cell
    height: int       # H
    font: int
    gap: int
    strip: int
    label_width: int  # L

    @property
    def left(self) -> int:
        return self.gap + (self.label_width + self.gap if self.label_width else 0)

    @property
    def image_width(self) -> int:
        return self.left + self.columns * (self.width + self.gap)

    @property
    def image_height(self) -> int:
        return self.gap + self.strip + self.rows * (self.height + self.gap)

    def origin(self, row: int, column: int) -> tuple[int, int]:
        """(x, y) of cell (row, column)'s top-left pixel."""
        return self.left + column * (self.width + self.gap), self.gap + self.strip + row * (self.height + self.gap)


def sheet_layout(rows: int, columns: int, width: int, height: int, row_labels: list[str]) -> SheetLayout:
    """The SheetLayout for a rows × columns grid of width × height cells; row labels at most
    max(2 W, ROW_LABEL_MIN) wide, so that labels of small cells stay legible."""
    base = layout(columns, width, height)
    label_width = 0
    if rows > 1:
        room = max(2 * width, ROW_LABEL_MIN)
        size = min((fitting_size(text, base.font, room) or MIN_FONT) for text in row_labels)
        drawn = [text_coverage(text, size) for text in row_labels]
        label_width = min(max((d.shape[1] for d in drawn if d is not None), default=0), room)
    return SheetLayout(rows=rows, columns=columns, width=width, height=height, font=base.font, gap=base.gap,
                       strip=base.strip, label_width=label_width)


def compose_sheet(cells: list[tuple[tuple[str, str], ...]], images: list[np.ndarray | None]) -> tuple[np.ndarray,
                                                                                                       SheetLayout]:
    """Cells (their (label, value) per axis, in product order) and their (h, w, 3) display images (None: failed)
    → the (image_height, image_width, 3) float32 sheet and its layout."""
    grid, row_labels = _sheet_grid(cells, [image.shape[:2] for image in images if image is not None])
    columns, height, width = grid.columns, grid.height, grid.width
    canvas = np.full((grid.image_height, grid.image_width, 3), BACKDROP, np.float32)
    for index, image in enumerate(images):
        row, column = divmod(index, columns)
        x, y = grid.origin(row, column)
        if image is None:
            canvas[y:y + height, x:x + width] = FAILED_RGB
            draw_text(canvas, "failed", (x, y, width, height), grid.font, align="center")
        else:
            canvas[y:y + image.shape[0], x:x + image.shape[1]] = image
    # Column labels over the first row; row labels left of each row.
    # Column labels read "label=value", or the value alone when any of them would not fit.
    texts, size = row_wording([(f"{label}={value}", value) for label, value in (cells[c][-1] for c in range(columns))],
                               grid.font, width)
    for column, text in enumerate(texts):
        draw_text(canvas, text, (grid.origin(0, column)[0], grid.gap, width, grid.strip), size, align="center")
    for row, text in enumerate(row_labels if grid.label_width else []):
        size = fitting_size(text, grid.font, grid.label_width) or grid.font
        draw_text(canvas, text, (grid.gap, grid.origin(row, 0)[1], grid.label_width, height), size)
    return canvas, grid


def _sheet_grid(cells: list[tuple[tuple[str, str], ...]], shapes: list[tuple[int, int]]) -> tuple[SheetLayout,
                                                                                                   list[str]]:
    """The layout of a sheet of `cells` whose images have these (h, w) (the largest sets the cell), and its
    row labels."""
    columns = len(dict.fromkeys(cell[-1] for cell in cells))
    rows = len(cells) // columns
    shapes = shapes or [(16, 16)]
    height, width = max(h for h, _ in shapes), max(w for _, w in shapes)
    row_labels = [", ".join(f"{label}={value}" for label, value in cells[r * columns][:-1]) for r in range(rows)]
    return sheet_layout(rows, columns, width, height, row_labels), row_labels


def check_sheet_memory(path: Path, cells: list, outputs: list[Path | None], budget: int | None) -> None:
    """Refuse (ImageError, one line) a contact sheet whose cells, from their files' headers, would not fit in
    `budget` bytes while held and composed; checked before any pixel is read. None: no budget."""
    if budget is None:
        return
    sizes = [image_header(output) if output is not None else None for output in outputs]
    known = [size for size in sizes if size]
    grid, _ = _sheet_grid(cells, [(h, w) for w, h, _ in known])
    need = (sum(w * h for w, h, _ in known) * CELL_BYTES_PER_PIXEL
            + grid.image_width * grid.image_height * SHEET_BYTES_PER_PIXEL
            + max((w * h * c for w, h, c in known), default=0) * COMPARE_BYTES_PER_SAMPLE)
    if need > budget:
        raise ImageError(f"{path}: the contact sheet of {len(cells)} cells of up to {grid.width}×{grid.height} "
                         f"pixels ({grid.image_width}×{grid.image_height} in all) needs ≈ {format_bytes(need)} of "
                         f"memory, above the {format_bytes(budget)} budget; render smaller cells, split the sweep, "
                         "or raise the budget (--max-memory)")


def write_contact_sheets(jobs: list, report, force: bool, budget: int | None = None) -> dict[str, str]:
    """For each sweep in the batch, DIR/<sweep>-contact.png, rewritten when a cell rendered or it is missing.

    Returns sweep name → sheet file name. Cells are read back from their files: a PNG as stored, an EXR as the
    PNG writer would show it (clamped, sRGB-encoded when its header says render.colour = "linear"). A sheet
    that would need more than `budget` bytes is refused (check_sheet_memory) before its cells are read.
    """
    by_name = {outcome.name: outcome for outcome in report.outcomes}
    sheets: dict[str, str] = {}
    for sweep in dict.fromkeys(job.sweep for job in jobs if job.sweep):
        members = [job for job in jobs if job.sweep == sweep]
        path = report.folder / f"{sweep}-contact.png"
        if path.is_file() and not force and all(by_name[job.name].status != "rendered" for job in members):
            sheets[sweep] = path.name
            continue
        outputs = [report.folder / by_name[job.name].outputs[0]
                   if by_name[job.name].status != "failed" and by_name[job.name].outputs else None for job in members]
        check_sheet_memory(path, [job.cell for job in members], outputs, budget)
        canvas, _ = compose_sheet([job.cell for job in members], [_cell_image(output, budget) for output in outputs])
        write_image(path, canvas)
        sheets[sweep] = path.name
    return sheets


def _cell_image(output: Path | None, budget: int | None) -> np.ndarray | None:
    """A cell's image as the sheet shows it, read back from its file (None: the cell failed or cannot be read)."""
    if output is None:
        return None
    try:
        # its own output, weighed with the sheet: a large render of a flat background is no bomb
        image = np.asarray(read_layer(output, max_memory=budget_of(budget)), np.float32)
    except ImageError:
        return None
    if output.suffix.lower() == ".exr":
        image = display_values(image, image_colour(output) or DISPLAY)
    return np.clip(image, 0.0, 1.0)
