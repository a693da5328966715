"""Jupyter: a render shown in a cell, flat / Gouraud / Phong side by side, and the live view in a cell.

    # docs: skip (a notebook's cells: live() starts a server)
    import raycast_phong as rp
    rp.render(rp.load_scene("scenes/default.toml"))  # a RenderResult shows itself: image, timings, plan
    rp.show("scenes/default.toml")        # flat | Gouraud | Phong, the lecture's figure
    live("scenes/default.toml")           # the `raycast-phong view` page, framed in the cell

Images are encoded exactly as `raycast-phong render -o x.png` stores them (image_bytes), and embedded as
data URIs, so a saved notebook keeps its figures.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import raycast_phong as rp
from raycast_phong.io.image_io import image_bytes
from raycast_phong.records import RenderResult
from raycast_phong.scene.overrides import shaded
from raycast_phong.scene.schema import Scene, ShadingModel

MODELS = tuple(ShadingModel)  # flat, Gouraud, Phong: the lecture's order
GAP = 8  # pixels between the images of Figures' PNG
MODEL_NAMES = {ShadingModel.FLAT: "flat", ShadingModel.GOURAUD: "Gouraud", ShadingModel.PHONG: "Phong"}


def figure_html(result: RenderResult, title: str = "") -> str:
    """One render as HTML: the image at its own size, its title, and a small table of the frame's figures,
    with the plan (kept and left-out stages, and why) folded under it."""
    height, width = result.image.shape[:2]
    png = base64.b64encode(image_bytes(result.image, colour=result.colour)).decode("ascii")
    rows = [("frame", f"{1000 * result.timings.get('frame', 0.0):.1f} ms"),
            ("in all", f"{1000 * sum(result.timings.values()):.1f} ms ("
             + ", ".join(f"{k} {1000 * v:.1f}" for k, v in result.timings.items()) + ")"),
            ("rays", f"{result.rays:,} ({result.rays_per_second / 1e6:.1f} M/s)"),
            ("triangles", f"{result.triangles:,}")]
    errors = getattr(result, "errors", None)  # an accuracy.measured result also carries its errors
    if errors is not None:
        rows.append(("error", f"RMSE {errors.rmse:.4g}, max {errors.max_error:.4g}, highlight loss "
                              f"{errors.highlight_loss:.1%} ({errors.reference})"))
    table = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th><td style='text-align:left'>"
                    f"{html.escape(v)}</td></tr>" for k, v in rows)
    stages = "".join(f"<tr><td style='text-align:left'>{'kept' if s.kept else 'left out'}</td>"
                     f"<td style='text-align:left'>{html.escape(s.name)}</td>"
                     f"<td style='text-align:left'>{html.escape(s.reason)}</td></tr>" for s in result.plan.stages)
    warnings = "".join(f"<li>{html.escape(w)}</li>" for w in result.plan.warnings)
    left_out = sum(not s.kept for s in result.plan.stages)
    caption = f"<b>{html.escape(title)}</b><br>" if title else ""
    # The figure is as wide as its image (the caption wraps under it): three of them fit side by side in a
    # JupyterLab output, where a wide table would push each onto its own line.
    return (f"<figure style='flex:0 0 auto;width:{width}px;margin:0 1em 1em 0;vertical-align:top'>"
            f"<img src='data:image/png;base64,{png}' width='{width}' height='{height}' alt='{html.escape(title)}'>"
            f"<figcaption style='font-size:smaller'>{caption}<table>{table}</table>"
            f"<details><summary>plan: {len(result.plan.stages) - left_out} stages kept, {left_out} left out"
            f"</summary><table>{stages}</table></details>"
            + (f"<ul>{warnings}</ul>" if warnings else "") + "</figcaption></figure>")


@dataclass
class Figures:
    """Renders shown side by side in a cell (Jupyter calls _repr_html_); `results` keeps them for code."""
    results: list[RenderResult]
    titles: list[str] = field(default_factory=list)

    def _repr_html_(self) -> str:
        titles = self.titles or [""] * len(self.results)
        # One row, scrolled sideways when the cell is narrower: the models are compared side by side.
        return ("<div style='display:flex;flex-wrap:nowrap;overflow-x:auto;align-items:flex-start'>"
                + "".join(figure_html(r, t) for r, t in zip(self.results, titles)) + "</div>")

    def _repr_png_(self) -> bytes:
        """The images in one PNG, left to right with GAP pixels of white between, top-aligned (for front ends
        that show PNGs only); each image's 8-bit values as `render -o x.png` stores them."""
        import numpy as np

        from raycast_phong.io.encoding import DISPLAY, to_8bit
        images = [to_8bit(r.image, r.colour) for r in self.results]
        height = max(image.shape[0] for image in images)
        width = sum(image.shape[1] for image in images) + GAP * (len(images) - 1)
        row = np.full((height, width, 3), 255, np.uint8)
        at = 0
        for image in images:
            row[:image.shape[0], at:at + image.shape[1]] = image
            at += image.shape[1] + GAP
        return image_bytes(row.astype(np.float32) / 255, colour=DISPLAY)

    def __repr__(self) -> str:
        titles = self.titles or [f"#{k}" for k in range(len(self.results))]
        return f"<Figures: {', '.join(titles)}: " + "; ".join(
            f"{r.image.shape[1]}×{r.image.shape[0]}, frame {1000 * r.timings.get('frame', 0.0):.1f} ms"
            for r in self.results) + ">"

    def __getitem__(self, index: int) -> RenderResult:
        return self.results[index]


def show(what: RenderResult | Iterable[RenderResult] | Scene | str | Path | None = None,
         models: Sequence[str] = MODELS, overrides: Sequence[str] = ()) -> Figures:
    """Show renders in a notebook cell, side by side.

    Parameters
    ----------
    what: a RenderResult or several (shown as they are); or a Scene, a scene or mesh file, or None for the
        default scene, rendered once per shading model in `models` (flat, Gouraud and Phong by default).
    overrides: `key.path=value` settings for a scene file, as `render --set` takes them
        (e.g. "render.width=320").

    Returns
    -------
    Figures: shown by Jupyter as the images with their timings; `.results` holds the RenderResults.

    Raises
    ------
    SceneError for a scene or file that cannot be loaded or rendered (as load_scene and render).
    """
    if isinstance(what, RenderResult):
        return Figures([what])
    if isinstance(what, Iterable) and not isinstance(what, (str, Path, Scene)):
        return Figures(list(what))
    if isinstance(what, Scene):
        scene = what
    else:
        scene = rp.load_scene(Path(what) if what is not None else rp.default_scene_path(), list(overrides))
    chosen = [ShadingModel(m) for m in models]
    results = [rp.render(shaded(scene, model)) for model in chosen]
    return Figures(results, [MODEL_NAMES[m] for m in chosen])


@dataclass
class Live:
    """A running `raycast-phong view` server framed in a cell; stop() ends it (the kernel's exit does too)."""
    url: str  # carries the page's token: never in a text output a notebook saves or shares (__repr__)
    height: int = 760
    _server: object = None

    def __repr__(self) -> str:
        address = self.url.split("?", 1)[0]
        return f"Live(view at {address}, {'running' if self._server is not None else 'stopped'}; .url has its token)"

    def _repr_html_(self) -> str:
        return (f"<iframe src='{html.escape(self.url)}' width='100%' height='{self.height}' "
                "style='border:1px solid #888'></iframe>")

    def stop(self) -> None:
        if self._server is not None:
            self._server.__exit__(None, None, None)
            self._server = None


def live(scene: str | Path | None = None, height: int = 760, port: int = 0) -> Live:
    """Start the live view of a scene or mesh file (None: the default scene) on a free loopback port and
    frame its page in the cell; the page's URL (with its token) is `.url`. Needs the [view] extra."""
    from raycast_phong.tools.view import running
    server = running(scene, port=port)
    url = server.__enter__()
    return Live(url, height, server)
