"""The work-precision study: orders on the exact sphere, the cost axis, stiff highlights, the report end to end."""

import base64
import html
import html.parser
import itertools
import math
import re

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.scene.load import read_scene_dict
from raycast_phong.tools.accuracy import mesh_coverage
from raycast_phong.tools.metrics import highlight_loss, measure, psnr, rmse, silhouette_pixels
from raycast_phong.tools.reference import analytic_reference
from raycast_phong.tools.study import (
    CSV_COLUMNS,
    OUTPUTS,
    StudyOptions,
    fastest,
    monotone_times,
    pareto_front,
    read_csv,
    run_study,
    variant,
)
from raycast_phong.tools.study_report import write_study

REQUIRED = ["model", "specular", "precision", "samples", "level", "triangles", "seconds", "rmse", "max_error",
            "psnr", "silhouette_pixels", "highlight_loss"]

SPHERE = """
ambient = 0.1
[render]
width = {size}
height = {size}
precision = "float64"
[camera]
position = [0, 0, 4]
fov = 40
[[lights]]
position = [2, 2, 3]
diffuse = 0.8
specular = 1.0
[materials.m]
ka = 1.0
kd = [0.7, 0.5, 0.3]
ks = 0.5
shininess = 16
[[objects]]
shape = "{shape}"
material = "m"
normals = "{normals}"
"""


PNG = b"\x89PNG\r\n\x1a\n"


def sphere_file(tmp_path, size=48, shape="icosphere", normals="exact"):
    path = tmp_path / "sphere.toml"
    path.write_text(SPHERE.format(size=size, shape=shape, normals=normals))
    return path


def fit(study, model, normals="scene"):
    return next(f for f in study.fits if f.model == model and f.key[1] == normals)


# ---------------------------------------------------------------- metrics

def test_metrics_on_small_arrays():
    a, b = np.zeros((2, 2, 3)), np.zeros((2, 2, 3))
    b[0, 0] = 0.3
    mask = np.ones((2, 2), bool)
    assert rmse(a, b, mask) == pytest.approx(math.sqrt(3 * 0.09 / 12))
    assert psnr(0.1) == pytest.approx(20) and psnr(0) == math.inf
    assert silhouette_pixels(np.array([1.0, 0.0, 0.5]), np.array([1.0, 1.0, 0.25])) == 2
    specular = np.zeros((2, 2, 3))
    specular[0, 0] = 0.3  # the reference's whole highlight sits in pixel (0, 0)
    assert highlight_loss(b, b, specular, mask) == 0
    assert highlight_loss(b - specular, b, specular, mask) == pytest.approx(1)
    assert highlight_loss(b - specular / 4, b, specular, mask) == pytest.approx(0.25)
    assert math.isnan(highlight_loss(a, a, np.zeros_like(a), mask))



def test_measure_compares_only_the_pixels_both_images_cover_and_its_mae_is_the_mean_absolute_error():
    """metrics.measure, hand-computed on 2×2 images: the reference leaves pixel (1, 1) uncovered, so its error
    of 1.0 counts as a silhouette pixel and not in the shading errors, which are over the 3 pixels both cover
    (9 channel values, three of them 0.3): MAE 0.1, RMSE √0.03, max 0.3."""
    from types import SimpleNamespace
    image, coverage = np.zeros((2, 2, 3)), np.ones((2, 2))
    reference = SimpleNamespace(image=np.zeros((2, 2, 3)), coverage=np.array([[1.0, 1.0], [1.0, 0.0]]),
                                specular=np.zeros((2, 2, 3)), kind="test")
    reference.image[0, 0], reference.image[1, 1] = 0.3, 1.0
    errors = measure(image, coverage, reference)
    assert errors.compared_pixels == 3 and errors.silhouette_pixels == 1
    assert errors.mae == pytest.approx(0.1) and errors.max_error == pytest.approx(0.3)
    assert errors.rmse == pytest.approx(math.sqrt(0.03))


def test_highlight_loss_takes_every_pixel_of_half_the_peak_and_counts_each_at_most_up_to_its_highlight():
    """highlight_loss's formula (docstring): the peak is every pixel whose specular sum is at least half the
    largest (0.9 and 0.6 here; 0.3 is out), and a pixel's overshoot does not make up for another's miss. The
    render doubles pixel A's highlight (0.9, counted as 0.9) and misses B's (0.6): 1 − 0.9 / 1.5 = 0.4."""
    mask = np.ones((2, 2), bool)
    specular = np.zeros((2, 2, 3))
    specular[0, 0], specular[0, 1], specular[1, 0] = 0.3, 0.2, 0.1  # sums 0.9 (A), 0.6 (B), 0.3
    reference = 0.1 + specular
    image = np.full((2, 2, 3), 0.1)
    image[0, 0] += 2 * specular[0, 0]
    assert highlight_loss(image, reference, specular, mask) == pytest.approx(0.4)


# ---------------------------------------------------------------- convergence orders and the cost axis

def _tiny_rows():
    from raycast_phong.tools.study import StudyRow
    names = StudyRow.__dataclass_fields__
    return [StudyRow(**{name: (0 if field.type in ("int", int) else "x" if field.type in ("str", str) else 0.0)
                        for name, field in names.items()})]


@pytest.fixture(scope="module")
def exact_sphere(tmp_path_factory):
    """The reduced study: an icosphere with exact and with mean normals, levels 3-6 (1,280 … 81,920
    triangles), 64 px, float64, three timing rounds (~15 s)."""
    path = sphere_file(tmp_path_factory.mktemp("exact"), size=64)
    return run_study(path, options=StudyOptions(levels=(3, 4, 5, 6), repeats=3, normals=("exact", "mean")))


def test_orders_on_the_exact_sphere_match_theory(exact_sphere):
    """Exact surface, exact vertex normals: flat 1 ± 0.15, Phong 2 ± 0.2 over the last three levels
    (measured 1.06 and 2.02); f = 16 is wide enough for Gouraud to be near 2 by level 6 (1.90)."""
    assert abs(fit(exact_sphere, "flat", "exact").order - 1) <= 0.15
    assert abs(fit(exact_sphere, "phong", "exact").order - 2) <= 0.2
    assert 1.7 <= fit(exact_sphere, "gouraud", "exact").order <= 2.2


def test_mean_normals_hold_the_icosphere_below_second_order(exact_sphere):
    """The icosphere's mean vertex normals are first-order along the seams of the original icosahedron, a
    strip about one edge wide, so Phong's RMSE falls like h^1.5 (measured 1.45-1.55), the same mesh with
    exact normals like h² — the measurement behind docs/accuracy.md's sentence."""
    mean, exact = fit(exact_sphere, "phong", "mean").order, fit(exact_sphere, "phong", "exact").order
    assert 1.2 <= mean <= 1.75 and exact - mean >= 0.25


def test_time_to_image_rises_with_triangles_in_every_model(exact_sphere):
    """The cost axis: level 3 → 6 is 64× the triangles. The triangle counts are exact; the geometry stage
    (min over the rounds, one thread, no shared cache) and the whole time to image grow by far more than
    a busy machine's noise between them (measured 1 → 25 ms and 3 → 60 ms)."""
    for model in ("flat", "gouraud", "phong"):
        rows = sorted((r for r in exact_sphere.rows if r.model == model and r.normals == "exact"),
                      key=lambda r: r.level)
        assert [r.triangles for r in rows] == [1280, 5120, 20480, 81920]
        coarse, fine = rows[0], rows[-1]
        assert fine.geometry_seconds > 2 * coarse.geometry_seconds
        assert fine.seconds_total_measured > coarse.seconds_total_measured
        # The sum of the stage minima (the geometry and BVH pooled over the settings that repeat them) never
        # exceeds the whole call's minimum, the time to image, which never exceeds its median.
        assert all(r.repeats == 3 and r.seconds_total_bound <= r.seconds_total_measured * (1 + 1e-9)
                   <= r.seconds_total_median * (1 + 1e-9) for r in rows)
        assert all(r.diagnosis_seconds > 0 for r in rows)  # timed in every call (prepare's 'diagnosis' timing)
        # seconds_total is the monotone fit of the measured: non-decreasing, same total.
        assert all(a.seconds_total <= b.seconds_total for a, b in itertools.pairwise(rows))
        assert sum(r.seconds_total for r in rows) == pytest.approx(sum(r.seconds_total_measured for r in rows))


def test_monotone_times_pool_adjacent_violators():
    """Hand-worked: measured 3, 1, 2, 5 ms → 2, 2, 2, 5 (the first three pooled to their mean)."""
    import dataclasses
    row = next(iter(_tiny_rows()))
    rows = [dataclasses.replace(row, level=level, seconds_total_measured=t / 1e3, seconds_total=t / 1e3)
            for level, t in enumerate((3.0, 1.0, 2.0, 5.0))]
    fitted = [r.seconds_total * 1e3 for r in monotone_times(rows)]
    assert fitted == pytest.approx([2.0, 2.0, 2.0, 5.0])


def _timed(level: int, minimum: float, median: float, error: float, model: str = "phong", **keys):
    """A hand-made row: its whole call's min and median (ms), its shading RMSE."""
    import dataclasses
    return dataclasses.replace(next(iter(_tiny_rows())), model=model, level=level, seconds_total_measured=minimum / 1e3,
                               seconds_total_median=median / 1e3, seconds_total=minimum / 1e3, rmse=error,
                               **{"samples": 1, "specular": "phong", "shininess": "scene", "normals": "scene",
                                  "precision": "float32", **keys})


def test_a_row_reports_the_whole_call_as_measured_and_the_stage_sum_as_a_bound():
    """The referee's level 6: the sum of each stage's fastest round was 220 ms where no whole call was under 340
    (median 387). Three runs, each fast in a different stage: time to image = the fastest call (340 ms), its median
    387; the stage sum (220 ms) is only the labelled lower bound; the diagnosis has its own column, not the rest."""
    from raycast_phong.tools.study import Setting, study_row
    runs = [(0.340, {"geometry": 0.150, "build": 0.040, "diagnosis": 0.030, "frame": 0.110}),
            (0.387, {"geometry": 0.060, "build": 0.090, "diagnosis": 0.035, "frame": 0.180}),
            (0.400, {"geometry": 0.160, "build": 0.050, "diagnosis": 0.025, "frame": 0.080})]
    from types import SimpleNamespace
    errors = SimpleNamespace(rmse=0.01, max_error=0.1, psnr=40.0, mae=0.005, silhouette_pixels=3, highlight_loss=0.0,
                             compared_pixels=100, reference="analytic")
    row = study_row(Setting("gouraud", None, "phong", "float32", 1, None, 6), runs, errors, 0.02, 0.1, 1000, 0.1)
    assert row.seconds_total_measured == pytest.approx(0.340) and row.seconds_total_median == pytest.approx(0.387)
    assert row.diagnosis_seconds == pytest.approx(0.025)
    assert row.rest_seconds == pytest.approx(min(0.340 - 0.330, 0.387 - 0.365, 0.400 - 0.315))
    assert row.seconds_total_bound == pytest.approx(0.060 + 0.040 + 0.025 + 0.080 + 0.010)
    assert row.seconds_total_bound < row.seconds_total_measured


def test_the_tables_and_the_advice_say_the_whole_call_not_a_stage_sum():
    """The column, the advice and the front called "measured" a sum of stage minima. Hand-made: min 30, 10, 25 ms,
    medians 33, 12, 27, a bound of 3 ms each: the tables' time columns and the advice give min and median."""
    import dataclasses

    from raycast_phong.tools.study import Study, advice, rows_table
    from raycast_phong.tools.study_report import fronts_table
    rows = [dataclasses.replace(_timed(level, t, m, err), seconds_total_bound=0.003)
            for level, t, m, err in ((0, 30.0, 33.0, 0.03), (1, 10.0, 12.0, 0.02), (2, 25.0, 27.0, 0.001))]
    study = Study(rows=rows, target=0.01, noise=None)
    table = rows_table(study)
    assert [line[table[0].index("ms to image, min")] for line in table[1:]] == ["30.00", "10.00", "25.00"]
    assert [line[table[0].index("median")] for line in table[1:]] == ["33.00", "12.00", "27.00"]
    assert [line[table[0].index("lower bound ms (Σ stage minima)")] for line in table[1:]] == ["3.00"] * 3
    assert not any("measured" in cell for cell in table[0])  # no column calls a composite "measured"
    fronts = fronts_table(study)
    assert {line[fronts[0].index("ms to image, min")] for line in fronts[1:]} <= {"30.00", "10.00", "25.00"}
    text = advice(study)
    assert "25.0–27.0 ms to image (RMSE 0.0010)" in text, text
    assert not re.search(r"(?<![\d.])3\.0", text)  # the bound is no time to image


def test_the_front_keeps_points_whose_time_ranges_overlap():
    """A point leaves the front only for one at least as accurate whose median run beat its fastest: 10–14 ms at
    RMSE 0.005 does not drop 12–13 ms at 0.006 (their ranges overlap), but drops 20–22 ms at 0.007."""
    from raycast_phong.tools.study import pareto_front
    a, b, c = _timed(0, 10, 14, 0.005), _timed(1, 12, 13, 0.006), _timed(2, 20, 22, 0.007)
    assert pareto_front([a, b, c]) == [a, b]
    assert pareto_front([_timed(0, 10, 11, 0.005), b]) == [_timed(0, 10, 11, 0.005)]


def test_the_advice_quotes_no_difference_inside_the_spread():
    """Two settings reach the target 0.1 ms apart with runs spread over 2 ms: the advice names both as as fast,
    and each model's fastest inside the winner's range is said to be so, without a difference to quote."""
    from raycast_phong.tools.study import Study, advice
    rows = [_timed(3, 10.0, 12.0, 0.002, precision="float32"), _timed(3, 10.1, 12.1, 0.002, precision="float64"),
            _timed(4, 10.05, 12.0, 0.004, model="gouraud"), _timed(5, 30.0, 31.0, 0.001)]
    text = advice(Study(rows=rows, target=0.005, noise=None))
    first = text.splitlines()[0]
    assert "as fast within the timing spread: phong L3 f64 1spp, gouraud L4 f32 1spp" in first, text
    assert "gouraud 10.1–12.0 ms (gouraud L4 f32 1spp, 0 triangles) (as fast, within the spread)" in first, text
    assert "0.1 ms" not in text and "0.05 ms" not in text


def _study_of(rows, **keys):
    from raycast_phong.tools.study import Study, fit_orders
    return Study(rows=rows, fits=fit_orders(rows), target=0.005, noise=None, **keys)


def _curve(model, orders, normals="scene", shininess="scene", samples=1, f_scene=16.0, start=0.1):
    """Levels 0-5, h = start·2^-L, RMSE = h^order (order per level pair given or one number)."""
    rows, error = [], 0.1
    for level in range(6):
        h = start * 2.0 ** -level
        if level:
            error *= 2.0 ** -(orders if isinstance(orders, float) else orders[level - 1])
        rows.append(_timed(level, 1.0 + level, 1.5 + level, error, model=model, normals=normals, edge_length=h,
                           shininess=shininess, samples=samples, image_rmse=error, precision="float32"))
    return rows


def test_every_order_far_from_theory_says_why_beside_it():
    """Phong settling at 1.56 with the icosphere's averaged normals (exact normals: 2.0), Gouraud at 0.6 while
    h·√f is above 0.4, flat at 1.36 with 2 × 2 samples: the orders table gives each reason next to the order, and
    an order near theory gets none."""
    from raycast_phong.tools.study import fits_table
    rows = (_curve("phong", 1.56, normals="mean") + _curve("phong", 2.0, normals="exact")
            + _curve("gouraud", 0.6, normals="exact", shininess="1000", start=1.0) + _curve("flat", 1.36, samples=2))
    table = fits_table(_study_of(rows, objects=(("icosphere", "mean"),)))
    reason = {(line[0], line[1].split(",")[0]): line[table[0].index("why not theory")] for line in table[1:]}
    assert table[0].index("why not theory") == table[0].index("theory") + 1
    assert "icosphere's seams" in reason["phong", "mean normals"] and "--normals exact" in reason[
        "phong", "mean normals"]
    assert reason["phong", "exact normals"] == "–"
    assert "h·√f" in reason["gouraud", "exact normals"] and "0.4" in reason["gouraud", "exact normals"]
    assert "2 × 2 samples" in reason["flat", "phong specular"]
    moving = _study_of(_curve("phong", (1.2, 1.4, 1.6, 1.8, 1.7), normals="exact"))
    assert "not settled" in fits_table(moving)[1][table[0].index("why not theory")]


def test_the_advice_says_where_one_sample_stops_the_whole_image_error():
    """At 1 sample per pixel the whole-image RMSE stalls once the silhouette's aliasing is what is left: the advice
    says after which level, with the numbers; when it keeps falling, it says nothing of it."""
    import dataclasses

    from raycast_phong.tools.study import advice
    rows = _curve("phong", 2.0)
    stalled = [dataclasses.replace(r, image_rmse=max(r.image_rmse, 4e-3)) for r in rows]
    text = advice(_study_of(stalled))
    level = next(r.level for r in stalled if r.image_rmse == 4e-3)
    assert f"At 1 sample per pixel the whole-image RMSE stops falling after level {level}" in text, text
    assert "aliasing" in text and "render.samples" in text
    assert "stops falling" not in advice(_study_of(rows))


def test_the_advice_names_the_gouraud_check_and_the_process_start():
    """The plan's Gouraud check is a named cost of Gouraud's time, not part of "the rest"; the times are said to be
    in-process, with one process start when it was measured."""
    import dataclasses

    from raycast_phong.tools.study import Machine, advice
    rows = [dataclasses.replace(r, diagnosis_seconds=0.0234) for r in _curve("gouraud", 2.0)] + _curve("phong", 2.0)
    text = advice(_study_of(rows))
    assert "Gouraud check" in text and "23.4 ms of 6.0–6.5 ms at level 5" in text, text
    assert "in-process" in text and "not measured" in text
    machine = Machine("Some CPU", 2, 2, "0.1.0", "3.11", "raycast-phong study", "/tmp", process_start=0.53)
    assert "0.53 s for one `raycast-phong render`" in advice(_study_of(rows, machine=machine))


def test_the_diagnosis_is_timed_inside_the_render_call(tmp_path):
    """render() times the plan's diagnosis as a stage of its own, so the study does not file it under the rest."""
    result = rp.render(rp.load_scene(sphere_file(tmp_path, size=8)))
    assert result.timings["diagnosis"] > 0 and result.timings["diagnosis"] < result.timings["geometry"] + 1.0


def test_the_front_and_the_advice_pick_the_fastest_setting_that_reaches_the_target(exact_sphere):
    from raycast_phong.tools.study import clearly_faster
    rows = exact_sphere.rows
    front = pareto_front(rows)
    assert all(a.seconds_total_measured <= b.seconds_total_measured for a, b in itertools.pairwise(front))
    for point in front:  # nothing is more accurate and faster beyond the spread than a point of the front
        assert not any(r.rmse <= point.rmse and clearly_faster(r, point) for r in rows)
    for point in set(map(id, rows)) - set(map(id, front)):
        row = next(r for r in rows if id(r) == point)
        assert any(r.rmse <= row.rmse and clearly_faster(r, row) for r in rows)
    assert len(front) >= 3 and min(r.rmse for r in front) == min(r.rmse for r in rows)
    best = fastest(rows, 0.005)
    assert best.rmse <= 0.005
    assert all(r.seconds_total_measured >= best.seconds_total_measured for r in rows if r.rmse <= 0.005)


def test_levels_are_chosen_until_the_orders_settle_or_the_budget_is_spent(tmp_path):
    path = sphere_file(tmp_path, size=16)
    settled = run_study(path, options=StudyOptions(levels=None, repeats=1, settle=10.0,
                                                   models=(rp.ShadingModel.PHONG,)))
    # Three windows of three levels need five levels; a settle of 10 accepts any three.
    assert sorted({r.level for r in settled.rows}) == [1, 2, 3, 4, 5] and "settled" in settled.levels_note
    spent = run_study(path, options=StudyOptions(levels=None, repeats=1, settle=0.0, budget=1e-3,
                                                 models=(rp.ShadingModel.PHONG,)))
    assert sorted({r.level for r in spent.rows}) == [1] and "budget" in spent.levels_note


def test_a_given_level_over_the_memory_budget_is_refused_before_anything_is_measured(tmp_path, monkeypatch):
    """Levels 1 and 7 of the sphere at a 20 MB budget: level 7 (≈ 330k triangles a render) is over it, so the
    study stops with the memory message before it compiles or renders anything, or computes a reference (before,
    after level 1's references and renders: seconds, and minutes for a large image)."""
    from raycast_phong.tools import study

    def not_now(*args, **kwargs):
        raise AssertionError("the study measured before it checked every level's memory")
    for name in ("reference_image", "render"):
        monkeypatch.setattr(study, name, not_now)
    for name in ("render", "prepare"):  # the study's session's
        monkeypatch.setattr(study.Renderer, name, not_now)
    with pytest.raises(rp.SceneError, match="above the 20 MB budget"):
        run_study(sphere_file(tmp_path, size=16), options=StudyOptions(levels=(1, 7), max_memory=20 << 20))


def test_gouraud_error_grows_with_shininess_and_highlight_loss(tmp_path):
    """The stiff case: the highlight narrows like 1/√f, below Gouraud's vertex spacing."""
    study = run_study(sphere_file(tmp_path, shape="uv_sphere", normals="mean"), options=StudyOptions(
        levels=(1, 4), models=(rp.ShadingModel.GOURAUD, rp.ShadingModel.PHONG), shininess=(10, 100, 1000),
        repeats=1))
    row = {(r.model, r.level, r.shininess): r for r in study.rows}
    # error_images.png draws every problem, not only the first
    assert sorted((image.model, image.problem) for image in study.images) == sorted(
        (model, f"phong specular, f = {f}") for model in ("gouraud", "phong") for f in ("10", "100", "1000"))
    finest = [row["gouraud", 4, f].rmse for f in ("10", "100", "1000")]
    assert finest[0] < finest[1] < finest[2]
    assert row["phong", 4, "1000"].highlight_loss < 0.1
    assert row["gouraud", 1, "1000"].highlight_loss > 0.8


def test_more_samples_shrink_the_silhouette_error(tmp_path):
    """Against the supersampled reference (4 × 4 rays per pixel) the silhouette pixels converge with the
    samples: 2 × 2 beats 1 × 1 at a fine level, where the mesh's own outline is close to the sphere's."""
    study = run_study(sphere_file(tmp_path, size=32), options=StudyOptions(
        levels=(5,), models=(rp.ShadingModel.PHONG,), samples=(1, 2), repeats=1))
    one, two = sorted(study.rows, key=lambda r: r.samples)
    assert two.silhouette_rmse < 0.8 * one.silhouette_rmse and two.image_rmse < one.image_rmse


# ---------------------------------------------------------------- the report end to end

class _Page(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.images, self.tables, self.open = [], 0, []

    def handle_starttag(self, tag, attrs):
        if tag not in ("img", "meta", "br"):
            self.open.append(tag)
        if tag == "img":
            self.images.append(dict(attrs)["src"])
        self.tables += tag == "table"

    def handle_endtag(self, tag):
        assert self.open and self.open.pop() == tag, f"</{tag}> closes nothing"


def test_small_study_writes_report_csv_plots_and_summary(tmp_path):
    path = sphere_file(tmp_path, size=24, shape="uv_sphere", normals="mean")
    options = StudyOptions(levels=(0, 1, 2), repeats=2, precisions=("float32", "float64"))
    study = run_study(path, options=options)
    written = write_study(study, tmp_path / "out")
    assert {p.name for p in (tmp_path / "out").iterdir()} == set(OUTPUTS.values())
    rows = read_csv(written["csv"])
    assert set(REQUIRED) <= set(rows[0]) and list(rows[0]) == CSV_COLUMNS
    assert len(rows) == 3 * 3 * 2
    for key in ("plot", "convergence", "silhouette", "highlight", "orders", "errors"):
        assert written[key].read_bytes()[:8] == PNG and written[key].stat().st_size > 10_000
    summary = written["summary"].read_text()
    assert "order (last 3 levels)" in summary and "Fastest to RMSE" in summary and "error_vs_time.png" in summary

    page = _Page()
    page.feed(written["report"].read_text())
    page.close()
    assert page.open == [] and page.tables >= 4
    assert len(page.images) == 6
    for source in page.images:
        assert source.startswith("data:image/png;base64,")
        assert base64.b64decode(source.split(",", 1)[1], validate=True)[:8] == PNG
    text = written["report"].read_text()
    assert "Timing noise" in text and "load average" in text and "Fastest to RMSE" in text
    # the run's record: CPU model, cores, the package's version, the command line; the process start's cost
    assert f"{study.machine.cpu}, {study.machine.cores} cores" in text and f"raycast-phong {rp.__version__}" in text
    assert html.escape(study.machine.command) in text and study.machine.cpu.strip()
    assert study.machine.process_start > 0 and "s for one `raycast-phong render`" in text

    # Re-measure one row: the same scene rendered again gives the CSV's errors (renders are deterministic).
    row = next(r for r in rows if r["model"] == "gouraud" and r["level"] == "1" and r["precision"] == "float32")
    base = rp.load_scene(path)
    scene = variant(base, read_scene_dict(path), model="gouraud", specular="phong", precision="float32", samples=1,
                    shininess=None, level=1, folder=str(tmp_path))
    again = rp.render(scene)
    errors = measure(again.image, mesh_coverage(scene), analytic_reference(scene))
    assert float(row["rmse"]) == errors.rmse and float(row["max_error"]) == errors.max_error
    assert int(row["silhouette_pixels"]) == errors.silhouette_pixels
    assert float(row["highlight_loss"]) == errors.highlight_loss
    assert int(row["triangles"]) == again.triangles == 448  # uv sphere, segments [16, 8]
    # the frame within the fastest whole call, which is within the median call
    assert 0 < float(row["seconds"]) <= float(row["seconds_total_measured"]) <= float(row["seconds_total_median"])


def test_a_cylinder_scene_can_be_studied(tmp_path):
    """accuracy.refined gave a cylinder segments [8·2^L, 1], which the format refuses (3..4096): the study of
    any scene with a cylinder stopped with a SceneError. Levels 0 and 1: 8 and 16 sections, 32 and 64 triangles."""
    path = tmp_path / "cylinder.toml"
    path.write_text(SPHERE.format(size=16, shape="cylinder", normals="exact").replace(
        'normals = "exact"', 'normals = "exact"\nrotate = [30, 20, 0]'))
    study = run_study(path, options=StudyOptions(levels=(0, 1), models=(rp.ShadingModel.PHONG,), repeats=1))
    assert sorted(r.triangles for r in study.rows) == [32, 64]


def test_a_process_start_that_cannot_be_measured_is_none_not_an_error(monkeypatch):
    """No temporary folder (a full disk): the advice says "not measured"; the study does not stop."""
    import tempfile

    from raycast_phong.tools import study

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(tempfile, "TemporaryDirectory", full)
    assert study.process_start() is None


@pytest.mark.parametrize("options", [{"repeats": 0}, {"levels": ()}, {"models": ()}])
def test_a_study_of_nothing_is_one_line_from_the_api_too(tmp_path, options):
    """run_study from Python (a notebook) with no repeat, level or model: the SceneError the command gives, not a
    ValueError of an empty min() deep in the timing (the command's --repeats has min=1 of its own). One repeat is
    the least that runs (checked by the tests above)."""
    with pytest.raises(rp.SceneError, match="at least one level, one model and one repeat"):
        run_study(sphere_file(tmp_path, size=8), options=StudyOptions(**{"levels": (1,), **options}))


def test_the_small_helpers_of_the_tables_on_hand_made_numbers():
    """spread is (median − min)/min: runs of 2, 3 and 10 ms spread 0.5 (the slow outlier does not count); the crop
    keeps `margin` pixels on both sides of the mask, inclusive; a time range never ends below its fastest run;
    a range from 100 ms on is in whole ms; h·√f at h = 0.1 and f = 100 is 1 highlight width."""
    import dataclasses

    from raycast_phong.tools.study import _crop, highlight_widths, ms, spread, time_range
    assert spread([2.0, 3.0, 10.0]) == pytest.approx(0.5) and spread([0.0, 0.0]) == 0.0
    mask = np.zeros((10, 12), bool)
    mask[5, 6] = True
    assert _crop(mask, margin=2) == (slice(3, 8), slice(4, 9))
    assert time_range(_timed(0, 5.0, 4.0, 0.1)) == (0.005, 0.005)
    assert ms(_timed(0, 100.0, 120.0, 0.1)) == "100–120 ms" and ms(_timed(0, 99.0, 120.0, 0.1)) == "99.0–120.0 ms"
    row = dataclasses.replace(_timed(0, 1.0, 1.0, 0.1), edge_length=0.1, shininess="100")
    assert highlight_widths(row, 16.0) == pytest.approx(1.0)


def test_no_aliasing_is_named_while_the_shading_error_falls_by_less_than_a_third():
    """The whole-image RMSE stalls at every level, but the shading RMSE falls only 2^-0.1 ≈ 7 % a level: the stall
    is not the silhouette's aliasing left over, so `aliasing` names no pair of levels."""
    import dataclasses

    from raycast_phong.tools.study import aliasing
    rows = [dataclasses.replace(r, image_rmse=0.5) for r in _curve("phong", 0.1)]
    assert aliasing(rows) is None
