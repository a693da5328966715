"""Make the pictures and the table of docs/stability.md (run from the repository root).

    .venv/bin/python docs/figures/make_stability_figures.py > /tmp/stability-table.md
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import raycast_phong as rp
from raycast_phong.tools import stability

OUT = Path("docs/images")


def row(images: list[np.ndarray], gap: int = 4) -> np.ndarray:
    spacer = np.ones((images[0].shape[0], gap, 3), np.float32)
    parts = []
    for image in images:
        parts += [image.astype(np.float32), spacer]
    return np.concatenate(parts[:-1], axis=1)


def stiff_gouraud_figure() -> None:
    """Top: Gouraud, bottom: Phong, on the 80-face sphere at f = 10, 100, 1000."""
    rows = []
    for model in ("gouraud", "phong"):
        rows.append(row([rp.render(stability.sphere_scene(f, 1, size=160, shading=model)).image
                         for f in (10.0, 100.0, 1000.0)]))
    spacer = np.ones((4, rows[0].shape[1], 3), np.float32)
    rp.write_image(OUT / "stability-stiff-gouraud.png", np.concatenate([rows[0], spacer, rows[1]], axis=0))


def interpolation_figure() -> None:
    """A receding quad shaded with Gouraud: perspective-correct weights (left), screen-space (right)."""
    images = []
    for interpolation in ("perspective", "screen"):
        scene = stability.receding_quad_scene(16.0, interpolation)
        scene = scene.model_copy(update={"render": scene.render.model_copy(update={"width": 160, "height": 200})})
        images.append(rp.render(scene).image)
    rp.write_image(OUT / "stability-interpolation.png", row(images))


def main() -> None:
    stiff_gouraud_figure()
    interpolation_figure()
    print("| case | property | measured | checked | margin | result |")
    print("|---|---|---|---|---|---|")
    for r in stability.run_all():
        checked = "—" if r.value is None else f"{r.value:.3g} {'≥' if r.at_least else '≤'} {r.limit:.3g}"
        margin = "—" if r.margin is None else ("∞" if r.margin == float("inf") else f"{r.margin:.3g}×")
        print(f"| {r.case} | {r.property} | {r.figure} | {checked} | {margin} | {'pass' if r.passed else 'FAIL'} |")


if __name__ == "__main__":
    main()
