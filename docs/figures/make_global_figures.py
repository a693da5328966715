"""Make the pictures and timings of docs/global.md (run from the repository root).

    .venv/bin/python docs/figures/make_global_figures.py

Writes docs/images/global-*.png and prints the timing table. Acne is shown by building the shadow
rays with offset_scale = 0 (no offset), which no scene key can ask for.
"""

from __future__ import annotations

import statistics
from pathlib import Path

import numpy as np

import raycast_phong as rp
from raycast_phong.renderer import pack
from raycast_phong.renderer import prepare as render_module

SCENE = Path("scenes/shadows.toml")
OUT = Path("docs/images")


def pair(left: np.ndarray, right: np.ndarray, gap: int = 6) -> np.ndarray:
    spacer = np.ones((left.shape[0], gap, 3), np.float32)
    return np.concatenate([left, spacer, right], axis=1)


def timed(overrides: list[str], repeats: int = 5) -> tuple[np.ndarray, float, dict]:
    scene = rp.load_scene(SCENE, overrides)
    rp.render(scene)  # kernels loaded
    runs = [rp.render(scene) for _ in range(repeats)]
    frame = statistics.median(r.timings["frame"] for r in runs)
    return runs[0].image, frame, runs[0].timings


def without_offset(overrides: list[str]) -> np.ndarray:
    original = render_module.prepare_shadows
    render_module.prepare_shadows = lambda *a, **k: pack.prepare_shadows(*a, offset_scale=0.0)
    try:
        return rp.render(rp.load_scene(SCENE, overrides)).image
    finally:
        render_module.prepare_shadows = original


def main() -> None:
    local, t_local, _ = timed(["render.mode=local"])
    hanika, t_hanika, split = timed([])
    none, t_none, _ = timed(["render.terminator=none"])
    rp.write_image(OUT / "global-local-vs-global.png", pair(local, hanika))
    acne = without_offset(["render.terminator=none"])
    rp.write_image(OUT / "global-acne.png", pair(acne, none))
    # The terminator: the sphere, enlarged 2× by pixel repetition.
    crop = (slice(60, 260), slice(120, 340))
    zoom = lambda image: image[crop].repeat(2, axis=0).repeat(2, axis=1)
    rp.write_image(OUT / "global-terminator.png", pair(zoom(none), zoom(hanika)))
    print("| render | frame (median of 5) | × local |")
    print("|---|---|---|")
    for name, seconds in (("local", t_local), ('global, terminator = "none"', t_none),
                          ('global, terminator = "hanika"', t_hanika)):
        print(f"| {name} | {seconds * 1e3:.1f} ms | {seconds / t_local:.2f} |")
    print("split (global, hanika):", {k: round(v * 1e3, 1) for k, v in split.items()})


if __name__ == "__main__":
    main()
