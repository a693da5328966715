"""Notebooks: a RenderResult shows itself inline, show() puts flat / Gouraud / Phong side by side, live() frames
the view's page in a cell, and docs/tutorial.ipynb runs from top to bottom (nbclient, as CI runs it)."""

from __future__ import annotations

import base64
import re
from html import escape
from pathlib import Path

import numpy as np
import pytest
from conftest import write_tiny_scene

import raycast_phong as rp
from raycast_phong.io.encoding import to_8bit

ROOT = Path(__file__).resolve().parents[2]


def images_in(html: str, folder: Path) -> list[np.ndarray]:
    """The data-URI PNGs of an HTML fragment, decoded to 8-bit (H, W, 3)."""
    found = []
    for k, encoded in enumerate(re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", html)):
        path = folder / f"figure-{k}.png"
        path.write_bytes(base64.b64decode(encoded))
        found.append(np.round(rp.read_image(path)[0] * 255).astype(np.uint8))
    return found


def test_a_render_shows_its_image_timings_and_plan_inline(tmp_path):
    scene = rp.load_scene(write_tiny_scene(tmp_path, 40, 30))
    result = rp.render(scene)
    html = result._repr_html_()
    [shown] = images_in(html, tmp_path)
    np.testing.assert_array_equal(shown, to_8bit(result.image))  # what `render -o x.png` would store
    assert "width='40' height='30'" in html and "<th style='text-align:left'>frame</th>" in html
    assert f"{result.rays:,}" in html and f"{result.triangles:,}" in html
    left_out = [s for s in result.plan.stages if not s.kept]
    assert left_out and all(f"<td style='text-align:left'>{escape(s.reason)}</td>" in html for s in left_out)


def test_show_puts_flat_gouraud_and_phong_side_by_side(tmp_path):
    path = write_tiny_scene(tmp_path, 80, 60)
    figures = rp.show(path, overrides=["render.width=40", "render.height=30"])
    html = figures._repr_html_()
    assert figures.titles == ["flat", "Gouraud", "Phong"] and html.index("flat") < html.index("Gouraud")
    shown = images_in(html, tmp_path)
    for image, model in zip(shown, ("flat", "gouraud", "phong")):
        expected = rp.render(rp.load_scene(path, ["render.width=40", "render.height=30", f'render.shading="{model}"',
                                                  f'objects.0.shading="{model}"']))
        np.testing.assert_array_equal(image, to_8bit(expected.image))
    assert (shown[0] != shown[2]).any() and (shown[1] != shown[2]).any()
    # Renders already made are shown as they are; a Scene object is rendered once per model.
    assert len(images_in(rp.show([figures[0], figures[2]])._repr_html_(), tmp_path)) == 2
    [flat] = rp.show(rp.load_scene(path, ["render.width=40", "render.height=30"]), models=["flat"]).results
    assert next(s.reason for s in flat.plan.stages if s.name == "shading_models") == "flat"
    np.testing.assert_array_equal(flat.image, figures[0].image)


def test_the_tutorial_runs_from_top_to_bottom():
    """docs/tutorial.ipynb executed in a fresh kernel, as CI runs it; its live-view cell is tagged skip-execution."""
    nbformat = pytest.importorskip("nbformat", reason="the notebook test needs the [test] extra's nbformat")
    nbclient = pytest.importorskip("nbclient", reason="the notebook test needs the [test] extra's nbclient")
    pytest.importorskip("ipykernel", reason="the notebook test needs the [test] extra's ipykernel")
    notebook = nbformat.read(ROOT / "docs" / "tutorial.ipynb", as_version=4)
    for cell in notebook.cells:
        if cell.cell_type == "code":
            cell.outputs = []  # the stored outputs are for readers; these come from this run
    nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(ROOT / "docs")}}).execute()
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    errors = [out for cell in code for out in cell.get("outputs", []) if out.output_type == "error"]
    assert not errors, errors
    html = [out["data"]["text/html"] for cell in code for out in cell.get("outputs", [])
            if "text/html" in out.get("data", {})]
    assert sum(page.count("data:image/png;base64,") for page in html) >= 3 + 3 + 2  # renders, shininess, models
    printed = "".join(out.get("text", "") for cell in code for out in cell.get("outputs", []))
    assert "highlight lost" in printed and "triangles" in printed
    # The closing sentence is the run's own: the model it names has the lowest error the run printed.
    said = re.search(r"In this run (\w+) shading reached the lowest error", printed)
    lowest = {model: float(rmse) for model, rmse in re.findall(r"^(\w+) +lowest RMSE ([0-9.]+)", printed, re.M)}
    assert said and lowest and said[1] == min(lowest, key=lowest.get), printed
    plot = next(cell.source for cell in code if "loglog" in cell.source)
    assert "pooled" in plot and "seconds_total_measured" in plot  # it says which times it draws
    assert any("image/png" in out.get("data", {}) for cell in code for out in cell.get("outputs", []))  # the plot
    assert "skip-execution" in code[-1].metadata.get("tags", [])  # the live page needs a browser


def test_png_bytes_hold_the_8bit_values_render_stores(tmp_path):
    """The view's frames are encoded in memory: out-of-range, odd-sized and 1×1 images decode (OpenImageIO) to
    film.to_8bit's values, what `render -o x.png` stores."""
    from raycast_phong.io.image_io import png_bytes
    rng = np.random.default_rng(7)
    for shape in [(1, 1, 3), (3, 5, 3), (37, 61, 3)]:
        image = rng.uniform(-0.5, 1.5, shape).astype(np.float32)
        path = tmp_path / "frame.png"
        path.write_bytes(png_bytes(image))
        np.testing.assert_array_equal(np.round(rp.read_image(path)[0] * 255).astype(np.uint8), to_8bit(image))


def test_results_have_a_png_and_a_one_line_repr(tmp_path):
    """Front ends that want a PNG get the one `render -o x.png` stores; a prompt gets one line, not a numpy dump."""
    path = write_tiny_scene(tmp_path, 40, 30)
    result = rp.render(rp.load_scene(path))
    (tmp_path / "shown.png").write_bytes(result._repr_png_())
    shown = np.round(rp.read_image(tmp_path / "shown.png")[0] * 255).astype(np.uint8)
    np.testing.assert_array_equal(shown, to_8bit(result.image))
    linear = rp.render(rp.load_scene(path, ['render.colour="linear"']))  # encoded through the sRGB curve
    (tmp_path / "linear.png").write_bytes(linear._repr_png_())
    shown = np.round(rp.read_image(tmp_path / "linear.png")[0] * 255).astype(np.uint8)
    np.testing.assert_array_equal(shown, to_8bit(linear.image, "linear"))
    assert (shown != to_8bit(linear.image)).any()
    text = repr(result)
    assert text.startswith("<RenderResult 40×30 float32, frame ") and "\n" not in text and "array(" not in text
    assert f"{result.rays:,} rays" in text and len(text) < 120
    from raycast_phong.tools.accuracy import measured
    exact = measured(rp.load_scene(path), result, "analytic")
    assert repr(exact).startswith("<MeasuredResult 40×30") and "RMSE" in repr(exact) and "array(" not in repr(exact)
    figures = rp.show(path, overrides=["render.width=40", "render.height=30"])
    assert repr(figures).startswith("<Figures: flat, Gouraud, Phong: 40×30") and "array(" not in repr(figures)
    (tmp_path / "figures.png").write_bytes(figures._repr_png_())
    row = np.round(rp.read_image(tmp_path / "figures.png")[0] * 255).astype(np.uint8)
    assert row.shape == (30, 3 * 40 + 2 * 8, 3)  # side by side, 8 white pixels between
    for k, one in enumerate(figures.results):
        np.testing.assert_array_equal(row[:, k * 48:k * 48 + 40], to_8bit(one.image))
    assert (row[:, 40:48] == 255).all()


def test_a_live_view_s_text_repr_does_not_carry_its_token():
    """Issue 49: a notebook saves a cell's text output; the Live object's repr carried the tokenised URL."""
    from raycast_phong.tools.notebook import Live
    live = Live("http://127.0.0.1:8123/?token=s3cr3t-t0ken", 700)
    text = repr(live)
    assert "s3cr3t" not in text and "http://127.0.0.1:8123/" in text and "stopped" in text
    assert "s3cr3t" in live._repr_html_()  # the frame itself needs it to connect
