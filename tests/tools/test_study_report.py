"""The study's figures, read as matplotlib draws them (no render: a study made by hand with known orders): the
convergence plot's fitted slopes and reference lines, a legend on every panel, integer levels on integer ticks,
no silhouette sweep from one sample count, and no "fastest" star where the times are noise."""

from __future__ import annotations

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


def made_study(samples=(1,), spread=0.05) -> Study:
    """Levels 0-4 with h = 2^-L and RMSE = 0.1 h^p, p the model's order (times rise with the level)."""
    rows = []
    for model, order in ORDERS.items():
        for level in range(5):
            for n in samples:
                h = 2.0 ** -level
                rows.append(row(model=model, level=level, samples=n, edge_length=h, rmse=0.1 * h ** order * n ** -0.1,
                                triangles=20 * 4 ** level, seconds_total=1e-3 * 4 ** level * n,
                                seconds_total_measured=1e-3 * 4 ** level * n, seconds=5e-4 * 4 ** level * n,
                                image_rmse=0.05 * h / n, silhouette_rmse=0.2 / n, highlight_loss=0.5 * h))
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
        reference = lines[f"slope {slope}"]
        h, error = reference.get_xdata(), reference.get_ydata()
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
