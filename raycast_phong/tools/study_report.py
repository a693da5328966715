"""The study's pictures and its one page: work-precision fronts, silhouettes, highlights, orders, error images.

One figure per question (study.OUTPUTS names the files):
- error_vs_time.png: shading RMSE against time to image (and, beside it, frame time) as measured, each point
  at its fastest run with a bar to its median run; one curve per model at the first value of the other axes,
  every other setting grey, the Pareto front (study.pareto_front: beyond the spread) ringed and labelled, the
  target and the fastest setting that reaches it marked;
- silhouette.png: silhouette RMSE against samples per pixel (one curve per level), and the whole-image
  error against time to image with its own front (samples trade cost for aliasing);
- highlight.png: highlight loss against level, per model and shininess;
- convergence.png: log shading RMSE against log edge length h, one panel per problem (specular model and
  shininess), one curve per model and normals, each with its fitted line (the order over the last FIT_WINDOW
  levels) and short guides of slopes 1 and 2 just below its finest two levels;
- orders.png: the local order against the edge length in highlight widths (h √f), per model, normals and
  shininess: Gouraud's crossover to 2 once the edges are well below the highlight's width;
- error_images.png: per problem and model, the render, the reference and the per-pixel error
  (difference.heat_map).
report.html embeds them (base64 PNG) with the tables, the fitted orders and their reasons, the advice, the
machine (CPU, cores, version, command line) and its timing noise.
matplotlib (Agg: files only, never a window) is imported here only, so only the study pays for it.
Every panel has its legend, outside the axes so it hides no point; a level axis has integer ticks; a log axis
has plain labels that do not overlap (_finish); where the timing rounds were noise (the machine's median
spread above NOISY_SPREAD) a time axis says so and no "fastest" star is drawn from it.
"""

from __future__ import annotations

import base64
import html
import io
import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import OutputError
from ..io.atomic import write_bytes, write_text
from ..io.encoding import to_8bit
from .difference import heat_map
from .study import (
    FIT_WINDOW,
    OUTPUTS,
    THEORY,
    TIMES,
    Study,
    StudyRow,
    advice,
    clearly_faster,
    curves,
    fastest,
    fits_table,
    highlight_widths,
    local_orders,
    pareto_front,
    problem_label,
    problems,
    rows_table,
    setting_label,
    slope,
    summary_markdown,
    time_range,
    write_csv,
)

COLOURS = {"flat": "tab:blue", "gouraud": "tab:orange", "phong": "tab:green"}
# A point's median run this much slower than its fastest (the median over the points): the order of the times
# along an axis is then the machine's, not the settings', so no setting is starred as the fastest from them. A
# quiet machine gives a few %; a study on a load of 9 over 2 cores gave 37 % with frame times out of order.
NOISY_SPREAD = 0.25
STYLES = ["-", "--", ":", "-."]
MARKERS = ["o", "s", "^", "D"]
CAPTIONS = {
    "plot": "Shading RMSE against time to image (left: the whole render() call) and frame time (right), as "
            "measured: each point at its fastest run, its bar reaching its median run. Coloured: one curve per model "
            "at the first value of the other axes, in level order; grey: every other setting; black rings: the "
            "Pareto front of all settings, labelled (a point leaves it only for one better in error and faster "
            "beyond both bars); star: the fastest setting that reaches the target (none where the timing rounds "
            "were noise).",
    "silhouette": "Left (when more than one sample count was swept): silhouette RMSE (pixels either image covers "
                  "only partly, against a supersampled reference) against samples per pixel side, one curve per "
                  "level. Right: the whole image's RMSE against time to image (fastest run, bar to the median), "
                  "every setting, its Pareto front ringed.",
    "convergence": "Shading RMSE against the mean edge length h, log–log, one panel per problem, one curve per "
                   f"model and normals; dashed: the fitted line over the last {FIT_WINDOW} levels (its slope is the "
                   "order in the table, with the reason when it is far from theory); grey, just below each curve's "
                   "finest two levels: slopes 1 (dotted) and 2 (dash-dot).",
    "highlight": "Highlight loss (share of the reference's specular peak the render misses) against level.",
    "orders": "Local convergence order (slope between successive levels) against the edge length measured in "
              "highlight widths, h·√f (for a unit radius). Theory: 1 for flat, 2 for Gouraud and Phong.",
    "errors": "Per problem and model: the render, the reference and the per-pixel error max over RGB |render − "
              "reference| (black 0, pale yellow the largest error over the pixels both cover fully; silhouette "
              "pixels saturate).",
}


@dataclass(frozen=True)
class Plot:
    path: Path
    png: bytes
    caption: str


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")  # files only, never a window
    import matplotlib.pyplot as plt
    return plt


def _panels(rows: int, columns: int, width: float, height: float):
    """A figure of rows × columns panels (always a 2-D array), 100 dpi, in matplotlib's constrained layout."""
    return _pyplot().subplots(rows, columns, figsize=(width, height), dpi=100, squeeze=False, layout="constrained")


def noisy(study: Study) -> bool:
    """Whether the study's timing rounds were noise (NOISY_SPREAD)."""
    return study.noise is not None and study.noise.median_spread > NOISY_SPREAD


def _noise_note(axes, study: Study) -> None:
    """Say on a time axis that its times are noise, with the figure the caption's machine line gives."""
    axes.text(0.02, 0.98, f"timing noise: a point's median run {100 * study.noise.median_spread:.0f} % above its "
              "fastest;\ntimes are not comparable, no fastest setting marked", transform=axes.transAxes,
              fontsize=7, va="top", color="tab:red", bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})


SUBS = (tuple(range(1, 10)), (1, 2, 5), (1,))  # log-axis labels, densest first: 1-9, 1-2-5, 1 × 10^k
OFFSETS = ((5, 4), (5, -11), (-5, 4), (-5, -11), (5, 14), (5, -21))  # points: where a front label may go
LABEL = "front label"  # the gid of a Pareto point's label (_finish)


def _set_log_labels(axis, subs: tuple) -> None:
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    axis.set_major_locator(LogLocator(subs=subs))
    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axis.set_minor_formatter(NullFormatter())


def _crowded(axis) -> bool:
    """Whether two of the axis's drawn tick labels overlap, or come within 2 pixels of each other."""
    boxes = [label.get_window_extent() for label in axis.get_ticklabels() if label.get_visible() and label.get_text()]
    return any(a.padded(2.0).overlaps(b) for a, b in itertools.combinations(boxes, 2))


def _finish(figure) -> None:
    """At the rendered size: every base-10 log axis gets plain labels, the densest SUBS whose labels do not overlap
    (matplotlib's labelled minor ticks, 2×10^1, 3×10^1 …, overlapped on a narrow time axis); then each Pareto
    point's label takes the first of OFFSETS where it overlaps no label placed before it."""
    from matplotlib.ticker import FixedLocator
    choice = {axis: 0 for axes in figure.axes for axis in (axes.xaxis, axes.yaxis)
              if axis.get_scale() == "log" and not isinstance(axis.get_major_locator(), FixedLocator)}
    for axis in choice:
        _set_log_labels(axis, SUBS[0])
    for _ in SUBS:
        figure.canvas.draw()
        crowded = [axis for axis, index in choice.items() if index + 1 < len(SUBS) and _crowded(axis)]
        if not crowded:
            break
        for axis in crowded:
            choice[axis] += 1
            _set_log_labels(axis, SUBS[choice[axis]])
    renderer = figure.canvas.get_renderer()
    for axes in figure.axes:
        placed = []
        for label in (text for text in axes.texts if text.get_gid() == LABEL):
            for offset in OFFSETS:
                label.xyann = offset
                label.set_horizontalalignment("left" if offset[0] > 0 else "right")
                if not any(label.get_window_extent(renderer).padded(1).overlaps(other) for other in placed):
                    break
            placed.append(label.get_window_extent(renderer))


def _log_log(axes) -> None:
    axes.set_xscale("log")
    axes.set_yscale("log")
    axes.grid(True, which="both", alpha=0.3)


def _legend(axes) -> None:
    """The legend outside the axes, on their right: inside, "best" still covered points of a crowded panel."""
    axes.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)


def _encode(figure) -> bytes:
    encoded = io.BytesIO()  # encode in memory: the file itself is written, checked and renamed by write_bytes
    figure.savefig(encoded, format="png")
    _pyplot().close(figure)
    return encoded.getvalue()


def _base(rows: list[StudyRow]) -> tuple:
    """The first value of the axes other than model and level: the curves drawn in colour."""
    first = rows[0]
    return (first.normals, first.precision, first.samples)


def _is_base(row: StudyRow, base: tuple) -> bool:
    return (row.normals, row.precision, row.samples) == base


def _measured(axes, rows: list[StudyRow], cost: str, error: str, fmt: str, **style) -> None:
    """Points at their fastest run with a bar to their median (study.time_range), in ms: the times measured."""
    low, high = np.array([time_range(r, cost) for r in rows]).T * 1e3 if rows else (np.array([]),) * 2
    axes.errorbar(low, [getattr(r, error) for r in rows], xerr=[np.zeros_like(low), high - low], fmt=fmt,
                  capsize=2, elinewidth=0.8, **style)


def _front(axes, rows: list[StudyRow], cost: str, error: str, label: bool) -> None:
    """The Pareto front (beyond the spread) as black rings, labelled with their settings when `label`."""
    front = [r for r in pareto_front(rows, error=error, cost=cost) if getattr(r, error) > 0]
    axes.scatter([getattr(r, cost) * 1e3 for r in front], [getattr(r, error) for r in front], s=70,
                 facecolors="none", edgecolors="black", lw=1.2, label="Pareto front (beyond the spread)", zorder=5)
    if label:
        for r in front:
            axes.annotate(setting_label(r), (getattr(r, cost) * 1e3, getattr(r, error)), textcoords="offset points",
                          xytext=OFFSETS[0], fontsize=6, gid=LABEL, in_layout=False)


def _front_axes(axes, rows: list[StudyRow], cost: str, target: float, label_front: bool, noise: bool) -> None:
    base = _base(rows)
    others = [r for r in rows if not _is_base(r, base) and r.rmse > 0]
    if others:
        _measured(axes, others, cost, "rmse", "o", ms=3, color="0.7", label="other settings", zorder=1)
    for key, curve in curves([r for r in rows if _is_base(r, base)]).items():
        _measured(axes, [r for r in curve if r.rmse > 0], cost, "rmse", "-o", ms=4, lw=1,
                  color=COLOURS.get(key[0], "black"), label=key[0], zorder=3)
    _front(axes, rows, cost, "rmse", label_front)
    axes.axhline(target, color="tab:red", lw=0.8, ls="--", label=f"target {target:g}")
    best = None if noise else fastest(rows, target)
    if best is not None:
        axes.plot([getattr(best, cost) * 1e3], [best.rmse], "*", ms=13, color="tab:red", zorder=6,
                  label="fastest to the target")
    _log_log(axes)


def front_figure(study: Study):
    groups = list(problems(study.rows).values())
    figure, grid = _panels(len(groups), 2, 15, 4.6 * len(groups))
    for rows, (left, right) in zip(groups, grid):
        _front_axes(left, rows, "seconds_total_measured", study.target, True, noisy(study))
        _front_axes(right, rows, "seconds", study.target, False, noisy(study))
        left.set_xlabel("time to image, ms (whole render() call: fastest run, bar to the median)")
        right.set_xlabel("frame time, ms (rays + shading: fastest run, bar to the median)")
        left.set_ylabel("shading RMSE (pixels both cover)")
        left.set_title(f"{Path(study.scene).name}: {problem_label(rows[0])}", fontsize=9)
        for axes in (left, right):
            _legend(axes)
            if noisy(study):
                _noise_note(axes, study)
    _finish(figure)
    return figure


def silhouette_figure(study: Study):
    plt = _pyplot()
    rows = next(iter(problems(study.rows).values()))
    model = rows[-1].model  # the last model swept (phong by default): its shading error is smallest
    first = rows[0]
    mine = [r for r in rows if r.model == model and (r.normals, r.precision) == (first.normals, first.precision)]
    counts = sorted({r.samples for r in mine})
    # A sweep over one sample count is one x value, no curve: the left panel is drawn only for a real sweep.
    figure, panels = _panels(1, 2 if len(counts) > 1 else 1, 13 if len(counts) > 1 else 8, 4.4)
    *left, right = panels[0]
    if left:
        left = left[0]
        levels = sorted({r.level for r in mine})
        colours = plt.get_cmap("viridis")(np.linspace(0, 0.9, max(len(levels), 1)))
        for colour, level in zip(colours, levels):
            points = sorted((r for r in mine if r.level == level), key=lambda r: r.samples)
            left.plot([r.samples for r in points], [r.silhouette_rmse for r in points], "-o", ms=4, color=colour,
                      label=f"level {level} ({points[0].triangles:,} tri)")
        left.set_xscale("log", base=2)
        left.set_yscale("log")
        left.set_xticks(counts, [str(n) for n in counts])  # the sample counts swept, whole numbers
        left.minorticks_off()
        left.set_xlabel("samples per pixel side (n × n rays per pixel)")
        left.set_ylabel("silhouette RMSE")
        left.set_title(f"{model}, {problem_label(first)}", fontsize=9)
        _legend(left)
        left.grid(True, which="both", alpha=0.3)
    finite = [r for r in rows if r.image_rmse > 0]
    for name in dict.fromkeys(r.model for r in finite):
        _measured(right, [r for r in finite if r.model == name], "seconds_total_measured", "image_rmse", "o", ms=3,
                  color=COLOURS.get(name, "black"), label=name)
    _front(right, finite, "seconds_total_measured", "image_rmse", True)
    _log_log(right)
    right.set_xlabel("time to image, ms (fastest run, bar to the median)")
    right.set_ylabel("whole-image RMSE against the supersampled reference")
    if len(counts) == 1:
        right.set_title(f"one sample count ({counts[0]}): no silhouette sweep (study --samples 1,2,4)", fontsize=9)
    _legend(right)
    if noisy(study):
        _noise_note(right, study)
    _finish(figure)
    return figure


def highlight_figure(study: Study):
    figure, ((axes,),) = _panels(1, 1, 10, 4.6)
    base = _base(study.rows)
    shininess = list(dict.fromkeys(r.shininess for r in study.rows))
    for key, curve in curves([r for r in study.rows if _is_base(r, base)]).items():
        curve = [r for r in curve if math.isfinite(r.highlight_loss)]
        if not curve:
            continue
        style = STYLES[shininess.index(key[5]) % len(STYLES)]
        label = key[0] + ("" if key[5] == "scene" else f", f = {key[5]}") + (
            f", {key[2]} specular" if len({r.specular for r in study.rows}) > 1 else "")
        axes.plot([r.level for r in curve], [r.highlight_loss for r in curve], style, marker="o", ms=4,
                  color=COLOURS.get(key[0], "black"), label=label)
    axes.set_xlabel("tessellation level (triangles ×4 per level)")
    axes.set_ylabel("highlight loss (0 all delivered, 1 none)")
    axes.set_ylim(-0.02, 1.02)
    from matplotlib.ticker import MaxNLocator
    axes.xaxis.set_major_locator(MaxNLocator(integer=True))
    axes.grid(True, alpha=0.3)
    _legend(axes)
    axes.set_title(f"{Path(study.scene).name}: the specular peak, {base[0]} normals, {base[1]}, {base[2]} spp",
                   fontsize=9)
    return figure


GUIDE_BELOW = 0.5  # the slope guides start this factor below a curve's last-but-one point: beside it, not on it


def convergence_figure(study: Study):
    """log RMSE against log h, one panel per problem: per curve (model and normals, at the problem's first precision
    and samples) its points, the fitted line of its order and, just below its finest two levels (beside that curve,
    where one pair for the panel would sit far from the others), guides of slopes 1 and 2."""
    groups = list(problems(study.rows).values())
    figure, panels = _panels(len(groups), 1, 10, 4.8 * len(groups))
    guided = False
    for rows, (axes,) in zip(groups, panels):
        first = rows[0]
        drawn = [(key, [r for r in curve if r.rmse > 0 and math.isfinite(r.rmse)]) for key, curve in curves(
            [r for r in rows if (r.precision, r.samples) == (first.precision, first.samples)]).items()]
        drawn = [(key, curve) for key, curve in drawn if len(curve) >= 2]
        normals = list(dict.fromkeys(key[1] for key, _ in drawn))
        for key, curve in drawn:
            h = np.array([r.edge_length for r in curve])
            error = np.array([r.rmse for r in curve])
            colour = COLOURS.get(key[0], "black")
            name = key[0] + ("" if key[1] == "scene" else f", {key[1]} normals")
            axes.plot(h, error, "-", marker=MARKERS[normals.index(key[1]) % 4], ms=4, lw=1, color=colour, label=name)
            window = slice(-min(FIT_WINDOW, len(curve)), None)  # the fit's levels: the finest FIT_WINDOW
            order = slope(curve[window])  # the order the table gives (fit_orders), and its least-squares intercept
            intercept = float(np.mean(np.log(error[window]) - order * np.log(h[window])))
            axes.plot(h[window], np.exp(intercept) * h[window] ** order, "--", lw=1.6, color=colour, alpha=0.8,
                      label=f"{name}: fit, order {order:.2f} (theory {THEORY[key[0]]:g})")
            span = h[-2:]  # the finest two levels: short enough not to cross the neighbouring curves
            for reference, style in ((1, ":"), (2, "-.")):
                axes.plot(span, GUIDE_BELOW * error[-2] * (span / span[0]) ** reference, style, color="0.45", lw=1.2,
                          label=f"slope {reference}" if not guided else f"_slope {reference}")
            guided = True
        if not drawn:
            axes.set_title("fewer than two levels with an error: no convergence to show", fontsize=9)
            continue
        guided = False  # each panel's legend names the guides
        _log_log(axes)
        axes.invert_xaxis()  # finer to the right, as the orders plot
        axes.set_xlabel("mean edge length h, world units (finer →)")
        axes.set_ylabel("shading RMSE (pixels both cover)")
        axes.set_title(f"{Path(study.scene).name}: {problem_label(first)}, {first.precision}, {first.samples} spp",
                       fontsize=9)
        _legend(axes)
    _finish(figure)
    return figure


def orders_figure(study: Study):
    figure, ((axes,),) = _panels(1, 1, 10, 4.8)
    first = study.rows[0]
    shininess = list(dict.fromkeys(r.shininess for r in study.rows))
    normals = list(dict.fromkeys(r.normals for r in study.rows))
    for key, curve in curves([r for r in study.rows if (r.precision, r.samples) == (first.precision, first.samples)
                              ]).items():
        points = local_orders(curve)
        if not points:
            continue
        label = key[0] + ("" if key[1] == "scene" else f", {key[1]} normals") + (
            "" if key[5] == "scene" else f", f = {key[5]}")
        axes.plot([highlight_widths(r, study.shininess) for r, _ in points], [o for _, o in points],
                  STYLES[shininess.index(key[5]) % len(STYLES)], marker=MARKERS[normals.index(key[1]) % 4], ms=4,
                  color=COLOURS.get(key[0], "black"), label=label)
    for theory in (1, 2):
        axes.axhline(theory, color="0.5", lw=0.8, ls=":")
    axes.set_xscale("log")
    axes.invert_xaxis()  # finer to the right
    axes.set_xlabel("edge length in highlight widths, h·√f (finer →)")
    axes.set_ylabel("local order, Δ log RMSE / Δ log h")
    axes.grid(True, which="both", alpha=0.3)
    if axes.get_legend_handles_labels()[0]:
        _legend(axes)
    else:
        axes.set_title("one level only: no order to show", fontsize=9)
    _finish(figure)
    return figure


def error_figure(study: Study):
    """Per problem and model (study.error_images): the render, the reference and the per-pixel error."""
    plt = _pyplot()
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import ListedColormap, Normalize
    images = study.images or []
    aspect = images[0].image.shape[0] / images[0].image.shape[1] if images else 1.0
    row_height = 3.8 * aspect + 0.7  # three panels of about 3.8 inches across, and a title
    figure, grid = plt.subplots(max(len(images), 1), 3, figsize=(12, row_height * max(len(images), 1)), dpi=100,
                                squeeze=False)
    several = len({picture.problem for picture in images}) > 1
    cmap = ListedColormap(heat_map(np.linspace(0, 1, 256)[None, :], 1.0)[0])
    for picture, (render_axes, reference_axes, error_axes) in zip(images, grid):
        render_axes.imshow(to_8bit(picture.image, study.colour), interpolation="nearest")
        render_axes.set_title(f"{picture.model}, level {picture.level} ({picture.triangles:,} triangles)"
                              + (f"\n{picture.problem}" if several else ""), fontsize=9)
        reference_axes.imshow(to_8bit(picture.reference, study.colour), interpolation="nearest")
        reference_axes.set_title("reference" + (f"\n{picture.problem}" if several else ""), fontsize=9)
        error_axes.imshow(heat_map(picture.difference, picture.scale), interpolation="nearest")
        error_axes.set_title(f"|error|, black 0 … yellow {picture.scale:.3g}", fontsize=9)
        figure.colorbar(ScalarMappable(Normalize(0, picture.scale), cmap), ax=error_axes, fraction=0.046, pad=0.02)
    for axes in grid.ravel():
        axes.set_xticks([])
        axes.set_yticks([])
    figure.tight_layout()
    return figure


# Each draws a matplotlib Figure (the tests read its panels); write_plots encodes and closes it.
FIGURES = {"plot": front_figure, "convergence": convergence_figure, "silhouette": silhouette_figure,
           "highlight": highlight_figure, "orders": orders_figure, "errors": error_figure}


def write_plots(study: Study, paths: dict[str, Path]) -> dict[str, Plot]:
    """Every figure encoded in memory and written atomically, in FIGURES' order. Raises WriteError."""
    written = {}
    for key, draw in FIGURES.items():
        png = _encode(draw(study))
        write_bytes(paths[key], png)
        written[key] = Plot(paths[key], png, CAPTIONS[key])
    return written


# ---------------------------------------------------------------- report.html

STYLE = """body{font:14px/1.45 system-ui,sans-serif;max-width:1180px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;font-size:12px;margin:.5em 0 1.5em}td,th{border:1px solid #ccc;padding:2px 6px}
th{background:#f3f3f3}td{text-align:right}td:first-child,td:nth-child(2){text-align:left}
img{max-width:100%;border:1px solid #eee}figure{margin:1em 0 2em}figcaption{font-size:13px;color:#444}
.advice{background:#f6fbf6;border-left:4px solid #4a4;padding:.5em 1em}.no{color:#b00}"""


def _table(rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(cell)}</th>" for cell in rows[0])
    body = "".join("<tr>" + "".join(f"<td>{html.escape(cell)}</td>" for cell in row) + "</tr>" for row in rows[1:])
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _figure(plot: Plot) -> str:
    data = base64.b64encode(plot.png).decode("ascii")
    return (f'<figure><img alt="{html.escape(plot.path.name)}" src="data:image/png;base64,{data}">'
            f"<figcaption><b>{html.escape(plot.path.name)}</b>: {html.escape(plot.caption)}</figcaption></figure>")


def fronts_table(study: Study) -> list[list[str]]:
    header = ["problem", "setting", "triangles", "ms to image, min", "median", "shading RMSE"]
    return [header] + [[problem_label(r), setting_label(r), f"{r.triangles:,}", f"{r.seconds_total_measured * 1e3:.2f}",
                        f"{r.seconds_total_median * 1e3:.2f}", f"{r.rmse:.2e}"]
                       for group in problems(study.rows).values() for r in pareto_front(group)]


def _ordered(curve: list[StudyRow]) -> str:
    """Whether a curve's measured times rise with the level beyond the spread of the rounds."""
    pairs = list(itertools.pairwise(curve))
    if all(clearly_faster(a, b) for a, b in pairs):
        return "yes"
    return "no" if any(clearly_faster(b, a) for a, b in pairs) else "within the spread"


def cost_table(study: Study) -> list[list[str]]:
    header = ["model", "curve", "triangles", "ms to image, min", "median", "rises beyond the spread"]
    return [header] + [[key[0], f"{key[1]} normals, {key[2]}, {key[3]}, {key[4]} spp, f={key[5]}",
                        " → ".join(f"{r.triangles:,}" for r in curve),
                        " → ".join(f"{r.seconds_total_measured * 1e3:.1f}" for r in curve),
                        " → ".join(f"{r.seconds_total_median * 1e3:.1f}" for r in curve), _ordered(curve)]
                       for key, curve in curves(study.rows).items()]


def report_html(study: Study, plots: dict[str, Plot]) -> str:
    """The self-contained page: the run's record, advice, fronts, orders, silhouettes, highlights, error images."""
    name = html.escape(Path(study.scene).name)
    advice_html = "".join(f"<p>{html.escape(line)}</p>" for line in advice(study).splitlines())
    noise = html.escape(study.noise.sentence()) if study.noise else "not measured"
    machine = html.escape(study.machine.sentence()) if study.machine else "not recorded"
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        f"<title>Work-precision study: {name}</title><style>{STYLE}</style></head><body>",
        f"<h1>Work-precision study: {name}</h1>",
        f"<p>{html.escape(study.levels_note)}. {len(study.rows)} settings. {html.escape(TIMES)} Every setting ran "
        "once per round, each round in a shuffled order.</p>",
        f"<p><b>Machine</b>: {machine}.</p>",
        f"<p><b>Timing noise</b>: {noise}. Errors and triangle counts do not depend on the machine.</p>",
        f'<div class="advice">{advice_html}</div>',
        "<h2>Error against time to image</h2>", _figure(plots["plot"]),
        "<h3>The Pareto front</h3>",
        "<p>A setting leaves the front only for one that is at least as accurate and faster beyond both points' "
        "spread (its median run faster than the other's fastest); settings whose time ranges overlap all stay.</p>",
        _table(fronts_table(study)),
        "<h2>Fitted convergence orders</h2>",
        f"<p>Least-squares slope of log RMSE against log mean edge length over each curve's last {FIT_WINDOW} levels "
        "(the asymptotic order), with the reason beside every order far from theory, the window one level "
        "coarser, and all levels.</p>",
        _table(fits_table(study)), _figure(plots["convergence"]), _figure(plots["orders"]),
        "<h2>Silhouettes and samples</h2>", _figure(plots["silhouette"]),
        "<h2>Highlights</h2>", _figure(plots["highlight"]),
        "<h2>Where the error lives</h2>", _figure(plots["errors"]),
        "<h2>Cost rises with the mesh</h2>",
        "<p>More triangles never take less work; levels a few ms apart can still be measured in either order, "
        "which the spread shows.</p>", _table(cost_table(study)),
        "<h2>Every setting</h2>", "<p>The CSV (study.csv) has every column.</p>",
        _table(rows_table(study)), "</body></html>", ""]
    return "\n".join(parts)


def write_study(study: Study, folder: Path) -> dict[str, Path]:
    """DIR/study.csv, the plots, DIR/summary.md and DIR/report.html, in that order, each replaced atomically.
    Raises WriteError when one cannot be written (those before it are written, it is unchanged)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OutputError(f"{folder}: cannot create the output folder ({error.strerror})") from None
    written = {key: folder / name for key, name in OUTPUTS.items()}
    write_csv(study, written["csv"])
    plots = write_plots(study, {key: written[key] for key in FIGURES})
    write_text(written["summary"], summary_markdown(study, plots))
    write_text(written["report"], report_html(study, plots))
    return written
