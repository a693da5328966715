"""Image differences, one home: the per-pixel difference of two images and its heat map.

Used by side-by-side (compare.py), `compare --diff`, the pytest plugin's diagnostics and the live view.
numpy only, so the pytest plugin that every test session loads pulls in no scene model or renderer.
"""

from __future__ import annotations

import numpy as np


def difference(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per pixel max over RGB of |image − reference|: two (H, W, 3) linear images → (H, W), float64 if either
    is (a render in float64 precision), else float32."""
    dtype = np.result_type(image, reference, np.float32)
    return np.abs(np.asarray(image, dtype) - np.asarray(reference, dtype)).max(axis=2)


# matplotlib's "inferno" (Smith & van der Walt, CC0) sampled at t = 0, 0.1, …, 1: black to pale yellow, its
# lightness rising steadily, so a brighter pixel always means a larger difference, also in grey print.
INFERNO = np.array([
    [0.001462, 0.000466, 0.013866], [0.087411, 0.044556, 0.224813], [0.258234, 0.038571, 0.406485],
    [0.416331, 0.090203, 0.432943], [0.578304, 0.148039, 0.404411], [0.735683, 0.215906, 0.330245],
    [0.865006, 0.316822, 0.226055], [0.954506, 0.468744, 0.099874], [0.987622, 0.645320, 0.039886],
    [0.964394, 0.843848, 0.273391], [0.988362, 0.998364, 0.644924]], np.float32)


def colour_map(t: np.ndarray) -> np.ndarray:
    """Values t in [0, 1] (clamped) of any shape S → (*S, 3) float32 display colours, INFERNO interpolated."""
    t = np.clip(np.asarray(t, np.float32), 0.0, 1.0)
    stops = np.linspace(0.0, 1.0, len(INFERNO))
    return np.stack([np.interp(t, stops, INFERNO[:, c]) for c in range(3)], axis=-1).astype(np.float32)


def heat_map(diff: np.ndarray, scale: float) -> np.ndarray:
    """An (H, W) difference → (H, W, 3) colours, 0 → black and `scale` → pale yellow (all black if scale is 0);
    a NaN or infinite difference is pale yellow too."""
    with np.errstate(invalid="ignore", divide="ignore"):
        t = diff / scale if scale > 0 else np.zeros_like(diff)
    return colour_map(np.where(np.isfinite(diff), t, 1.0))


def difference_map(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """`compare --diff`: the heat map of two (H, W, C) images, scaled to their largest finite difference."""
    with np.errstate(invalid="ignore"):  # inf − inf is NaN: drawn at the top of the scale, never a warning
        diff = difference(a, b)
    finite = diff[np.isfinite(diff)]
    return heat_map(diff, float(finite.max()) if finite.size else 0.0)
