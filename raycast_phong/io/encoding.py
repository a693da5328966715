"""Display encoding for 8-bit image files.

The model's values are display values (as in the lecture's shader), so a PNG stores them clamped to
[0, 1] with no gamma curve; `srgb=True` applies the sRGB transfer curve instead (IEC 61966-2-1).
"""

from __future__ import annotations

import numpy as np


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve on values clamped to [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def to_8bit(image: np.ndarray, srgb: bool = False, rows_per_band: int = 256) -> np.ndarray:
    """Display values to uint8: clamp to [0, 1] (never wrap), optional sRGB, round to nearest.

    Converted in bands of rows, so a 16k × 16k image needs no full-size float temporaries.
    """
    out = np.empty(image.shape, np.uint8)
    for row in range(0, image.shape[0], rows_per_band):
        band = np.asarray(image[row:row + rows_per_band], np.float32)
        values = srgb_encode(band) if srgb else np.clip(band, 0.0, 1.0)
        # NaN would cast to an arbitrary byte; the renderer never produces one, but a caller's array might.
        values = np.nan_to_num(values, nan=0.0)
        out[row:row + rows_per_band] = np.round(values * 255.0)
    return out
