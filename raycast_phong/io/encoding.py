"""Display encoding for 8-bit image files, as the scene's `render.colour` asks (docs/scene-format.md).

"display" (the default, the lecture's and fixed-function GL's): the model's values are display values, and a
PNG stores them clamped to [0, 1] with no curve. "linear" (glTF's): the model's values are linear light, and a
PNG stores them through the sRGB transfer curve (IEC 61966-2-1). An EXR stores the values unencoded either way.
"""

from __future__ import annotations

import numpy as np

DISPLAY, LINEAR = "display", "linear"
COLOURS = (DISPLAY, LINEAR)  # render.colour's values, the default first


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve on values clamped to [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def display_values(image: np.ndarray, colour: str) -> np.ndarray:
    """The values a display shows for an image rendered in `colour`: the image itself ("display", unclamped:
    the 8-bit writer clamps), or its sRGB encoding ("linear", clamped to [0, 1] by the curve)."""
    return srgb_encode(image) if colour == LINEAR else image


def to_8bit(image: np.ndarray, colour: str = DISPLAY, rows_per_band: int = 256) -> np.ndarray:
    """An image rendered in `colour` to uint8: clamp to [0, 1] (never wrap), the sRGB curve for "linear",
    round to nearest.

    Converted in bands of rows, so a 16k × 16k image needs no full-size float temporaries.
    """
    if colour not in COLOURS:
        raise ValueError(f"colour {colour!r}; allowed: {', '.join(COLOURS)}")
    out = np.empty(image.shape, np.uint8)
    for row in range(0, image.shape[0], rows_per_band):
        values = display_values(np.asarray(image[row:row + rows_per_band], np.float32), colour)
        # Clamped by fmax and fmin, which (unlike clip) take the number over a NaN: a NaN would cast to an
        # arbitrary byte; the renderer never produces one, but a caller's array might. In place after the first
        # pass: the bytes of clip + nan_to_num, without their extra passes (the live view encodes every draft).
        values = np.fmax(values, 0.0)
        np.fmin(values, 1.0, out=values)
        np.multiply(values, 255.0, out=values)
        out[row:row + rows_per_band] = np.round(values, out=values)
    return out
