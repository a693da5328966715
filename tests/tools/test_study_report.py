"""The study's figures, read as matplotlib draws them (no render: a study made by hand with known orders): the
convergence plot's fitted slopes and slope guides beside every curve, every problem drawn, measured times with
their spread, a legend on every panel that hides no point, log labels that do not overlap at the rendered size,
integer levels on integer ticks, no silhouette sweep from one sample count, and no "fastest" star where the times
are noise."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from raycast_phong.tools import study_report
from raycast_phong.tools.study import FIT_WINDOW, MachineNoise, Study, StudyRow, fit_orders

ORDERS = {"flat": 1.0, "gouraud": 2.0, "phong": 2.0}


def row(**keys) -> StudyRow:
    blank = {name: (0 if field.type in ("int", int) else "scene" if field.type in ("str", str) else 0.0)
             for name, field in StudyRow.__dataclass_fields__.items()}
    return StudyRow(**{**blank, "normals": "exact", "specular": "phong", "precision": "float64", "samples": 1,
                       "repeats": 3, "compared_pixels": 100, **keys})


def made_study(samples=(1,), spread=0.05, shininess=("scene",), growth=4.0) -> Study:
    """Levels 0-4 with h = 2^-L and RMSE = 0.1 h^p (× f^0.1), p the model's order; times rise with the level by
    `growth` (a growth of 1.3 keeps them within half a decade, as at the coarse levels of a real study), each
    median 20 % above its minimum; the monotone fit (seconds_total) is set apart from both, at 0.7 × the minimum."""
    rows = []
    for model, order in ORDERS.items():
        for f in shininess:
            for level in range(5):
                for n in samples:
                    h, scale = 2.0 ** -level, 1.0 if f == "scene" else float(f) ** 0.1
                    fastest = 8e-3 * growth ** level * n
                    rows.append(row(model=model, level=level, samples=n, edge_length=h, shininess=f,
                                    rmse=0.1 * scale * h ** order * n ** -0.1, triangles=20 * 4 ** level,
                                    seconds_total=0.7 * fastest, seconds_total_measured=fastest,
                                    seconds_total_median=1.2 * fastest, seconds=0.5 * fastest,
                                    seconds_median=0.6 * fastest, image_rmse=0.05 * h / n, silhouette_rmse=0.2 / n,
                                    highlight_loss=0.5 * h))
    noise = MachineNoise(2, (1.0, 1.0, 1.0), (1.0, 1.0, 1.0), spread, 2 * spread, 3, 1.0)
    return Study(rows=rows, fits=fit_orders(rows), scene="s.toml", target=1e-3, noise=noise)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    study_report._pyplot().close("all")


def test_the_convergence_plot_has_each_curves_fit_and_the_reference_slopes():
    figure = study_report.convergence_figure(made_study())
    (axes,) = figure.axes
    assert axes.get_xscale() == axes.get_yscale() == "log"
    lines = {line.get_label(): line for line in axes.get_lines()}
    for model, order in ORDERS.items():
        fit = lines[f"{model}, exact normals: fit, order {order:.2f} (theory {order:g})"]
        h, error = fit.get_xdata(), fit.get_ydata()
        assert len(h) == FIT_WINDOW
        np.testing.assert_allclose(np.diff(np.log(error)) / np.diff(np.log(h)), order, rtol=1e-9)
        np.testing.assert_allclose(error, 0.1 * h ** order, rtol=1e-9)  # through the points themselves
    for slope in (1, 2):
        guides = [line for line in axes.get_lines() if line.get_label().lstrip("_") == f"slope {slope}"]
        assert len(guides) == len(ORDERS)  # one per curve
        for guide in guides:
            h, error = guide.get_xdata(), guide.get_ydata()
            np.testing.assert_allclose(np.diff(np.log(error)) / np.diff(np.log(h)), slope, rtol=1e-9)
    assert axes.get_legend() is not None


@pytest.mark.parametrize("samples", [(1,), (1, 2, 4)])
def test_every_panel_of_every_figure_has_its_legend(samples):
    study = made_study(samples)
    for name in ("plot", "convergence", "silhouette", "highlight", "orders"):
        figure = study_report.FIGURES[name](study)
        for axes in figure.axes:
            if axes.has_data():
                assert axes.get_legend() is not None, (name, axes.get_title(), axes.get_xlabel())


def test_a_silhouette_sweep_of_one_sample_count_draws_no_curve_of_one_point():
    one = study_report.silhouette_figure(made_study((1,)))
    assert len(one.axes) == 1 and "silhouette RMSE" not in one.axes[0].get_ylabel()
    swept = study_report.silhouette_figure(made_study((1, 2, 4)))
    left = swept.axes[0]
    assert left.get_ylabel() == "silhouette RMSE"
    assert list(left.get_xticks()) == [1, 2, 4]
    assert [label.get_text() for label in left.get_xticklabels()] == ["1", "2", "4"]


def test_levels_are_on_integer_ticks():
    figure = study_report.highlight_figure(made_study())
    figure.canvas.draw()
    ticks = [t for t in figure.axes[0].get_xticks() if -0.5 <= t <= 4.5]
    assert ticks and all(float(t).is_integer() for t in ticks), ticks


def _stars(figure) -> int:
    return sum(line.get_marker() == "*" for axes in figure.axes for line in axes.get_lines())


def test_noisy_times_are_said_on_the_plot_and_star_no_fastest_setting():
    quiet = study_report.front_figure(made_study(spread=0.05))
    assert _stars(quiet) == 2  # time to image and frame time: the fastest setting reaching the target
    noisy = study_report.front_figure(made_study(spread=1.92))  # the 192 %
    assert _stars(noisy) == 0
    for axes in noisy.axes:
        assert any("timing noise" in text.get_text() and "192 %" in text.get_text() for text in axes.texts)
    assert not any("timing noise" in text.get_text() for axes in quiet.axes for text in axes.texts)
    assert math.isclose(study_report.NOISY_SPREAD, 0.25)


def _points(figure) -> list[tuple[float, float]]:
    """Display coordinates of every data point drawn in data coordinates: line vertices and scatter offsets."""
    points = []
    for axes in figure.axes:
        for line in axes.get_lines():
            if line.get_transform() == axes.transData and len(line.get_xdata()):
                xy = np.column_stack([line.get_xdata(), line.get_ydata()]).astype(float)
                points += map(tuple, axes.transData.transform(xy))
        for collection in axes.collections:
            if len(collection.get_offsets()) and collection.get_offset_transform() == axes.transData:
                points += map(tuple, axes.transData.transform(collection.get_offsets()))
    return points


def _rendered(figure):
    """The figure drawn as write_plots draws it (savefig at its own size and dpi)."""
    figure.savefig(io.BytesIO(), format="png")
    return figure


def crowded_study() -> Study:
    """made_study over 1, 2 and 4 samples, and a float32 copy of every point scattered (seeded) over the panels:
    grey points everywhere, so no corner inside the axes is free for a legend."""
    import dataclasses
    study, rng = made_study((1, 2, 4), growth=2.0), np.random.default_rng(1)
    for r in list(study.rows):
        k, e = rng.uniform([0.5, 0.3], [8, 30])
        study.rows.append(dataclasses.replace(
            r, precision="float32", seconds_total_measured=r.seconds_total_measured * k,
            seconds_total_median=r.seconds_total_median * k, seconds=r.seconds * k, seconds_median=r.seconds_median * k,
            rmse=r.rmse * e, image_rmse=r.image_rmse * e))
    return study


FIGURE_STUDIES = [made_study(), made_study((1, 2, 4)), made_study(growth=1.3, shininess=("10", "1000")),
                  made_study(growth=1.15), crowded_study()]


@pytest.mark.parametrize("study", FIGURE_STUDIES,
                         ids=["wide", "samples", "narrow-two-problems", "very-narrow", "crowded"])
@pytest.mark.parametrize("name", ["plot", "convergence", "silhouette", "highlight", "orders"])
def test_no_legend_hides_a_point_and_no_log_labels_overlap(name, study):
    """At the rendered size: no legend box covers a plotted point (a legend "best" inside a crowded panel did), and
    no two tick labels of an axis overlap (matplotlib labelled 2×10^1, 3×10^1 … on a narrow time axis)."""
    figure = _rendered(study_report.FIGURES[name](study))
    points = _points(figure)
    for axes in figure.axes:
        legend = axes.get_legend()
        if legend is not None:
            box = legend.get_window_extent()
            assert not [p for p in points if box.contains(*p)], (name, axes.get_title())
        for axis in (axes.xaxis, axes.yaxis):
            boxes = [t.get_window_extent() for t in axis.get_ticklabels() if t.get_visible() and t.get_text()]
            assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:]), (
                name, [t.get_text() for t in axis.get_ticklabels()])
            if axis.get_scale() == "log" and axis is axes.xaxis and name in ("plot", "silhouette"):
                assert len(boxes) >= 2, (name, [t.get_text() for t in axis.get_ticklabels()])


def test_the_time_axes_draw_the_measured_times_with_their_spread():
    """Every point of the time plots is a measured time, its fastest whole call with a bar to its median (in ms),
    never the monotone fit (which put several points at one time, on a vertical line)."""
    study = made_study(growth=1.3)
    measured = {round(r.seconds_total_measured * 1e3, 9): r for r in study.rows}
    frames = {round(r.seconds * 1e3, 9): r for r in study.rows}
    fitted = {round(r.seconds_total * 1e3, 9) for r in study.rows}
    figure = study_report.front_figure(study)
    left, right = figure.axes
    for axes, drawn, median in ((left, measured, "seconds_total_median"), (right, frames, "seconds_median")):
        bars = [c for c in axes.containers if type(c).__name__ == "ErrorbarContainer"]
        assert bars
        for container in bars:
            xs = [round(x, 9) for x in container.lines[0].get_xdata()]
            assert xs and all(x in drawn and x not in fitted for x in xs)
            (segments,) = [c.get_segments() for c in container.lines[2]]
            for x, segment in zip(xs, segments):  # from the fastest run to the median run
                assert segment[0][0] == pytest.approx(x) and segment[1][0] == pytest.approx(
                    getattr(drawn[x], median) * 1e3)
    assert "fastest run, bar to the median" in left.get_xlabel()


def test_every_problem_is_drawn_in_the_convergence_and_error_figures():
    """A study over two shininesses: convergence.png has a panel per problem, error_images.png a row per problem
    and model (only the first problem was drawn)."""
    from raycast_phong.tools.study import ErrorImage
    study = made_study(shininess=("10", "1000"))
    figure = study_report.convergence_figure(study)
    assert [axes.get_title().split(": ")[1].split(",")[:2] for axes in figure.axes if axes.has_data()] == [
        ["phong specular", " f = 10"], ["phong specular", " f = 1000"]]
    picture = np.zeros((4, 6, 3))
    study.images = [ErrorImage(model, 2, 320, f"phong specular, f = {f}", picture, picture, picture[..., 0], 1.0)
                    for f in ("10", "1000") for model in ORDERS]
    titles = [axes.get_title() for axes in study_report.error_figure(study).axes if axes.get_title()]
    for f in ("10", "1000"):
        for model in ORDERS:
            assert any(title.startswith(f"{model}, level 2") and f"f = {f}" in title for title in titles), titles


def test_the_slope_guides_sit_beside_every_curve():
    """Guides through the first curve's finest point were far from the others (one decade above Phong); each curve
    now has both slopes within a factor 3 below its own finest two levels."""
    figure = study_report.convergence_figure(made_study())
    (axes,) = [a for a in figure.axes if a.has_data()]
    curves = [line for line in axes.get_lines() if line.get_marker() not in ("None", None, "") and len(
        line.get_xdata()) > 2]
    guides = [line for line in axes.get_lines() if line.get_label().lstrip("_").startswith("slope")]
    for curve in curves:
        h, error = curve.get_xdata(), curve.get_ydata()
        for slope in (1, 2):
            assert any(guide.get_label().lstrip("_") == f"slope {slope}" and guide.get_xdata()[0] == h[-2]
                       and error[-2] / 3 <= guide.get_ydata()[0] < error[-2] for guide in guides), (curve.get_label(),
                                                                                                     slope)


def test_a_setting_whose_rmse_is_exactly_the_target_reaches_it():
    """fastest and as_fast take the settings whose RMSE is *at most* the target: one exactly at it is the fastest
    when it is quickest, and is as fast as the best when their times overlap. Catches `<` for `<=`."""
    from raycast_phong.tools.study import as_fast, fastest
    exact = row(model="gouraud", rmse=0.01, seconds_total_measured=0.010, seconds_total_median=0.011)
    slower = row(model="phong", rmse=0.001, seconds_total_measured=0.020, seconds_total_median=0.021)
    overlapping = row(model="flat", rmse=0.01, seconds_total_measured=0.0105, seconds_total_median=0.0115)
    assert fastest([exact, slower], 0.01) is exact
    assert fastest([exact, slower], math.nextafter(0.01, 0)) is slower
    assert as_fast([exact, slower, overlapping], exact, 0.01) == [overlapping]
