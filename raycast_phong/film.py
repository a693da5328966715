"""Gather shaded tiles into the (H, W, 3) image and its layers; encode display values for 8-bit files.

The model's values are display values (as in the lecture's shader), so a PNG stores them clamped to
[0, 1] with no gamma curve; `srgb=True` applies the sRGB transfer curve instead (IEC 61966-2-1).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .shading import TileImage

TERM_LAYERS = ("ambient", "diffuse", "specular", "emission")


@dataclass(eq=False)
class Film:
    """The whole image and the requested layers, filled tile by tile (each tile owns its rows)."""
    width: int
    height: int
    aovs: tuple[str, ...]
    rgb: np.ndarray = field(init=False)
    layers: dict[str, np.ndarray] = field(init=False)

    def __post_init__(self) -> None:
        self.rgb = np.zeros((self.height, self.width, 3), np.float32)
        channels = {"depth": 1, "normal": 3, "face": 1, **{name: 3 for name in TERM_LAYERS}}
        self.layers = {name: np.zeros((self.height, self.width, channels[name]), np.float32) for name in self.aovs}

    def put(self, row0: int, tile: TileImage) -> None:
        rows = slice(row0, row0 + tile.rgb.shape[0])
        self.rgb[rows] = tile.rgb
        for name, layer in self.layers.items():
            if name in TERM_LAYERS:
                layer[rows] = tile.terms[:, :, TERM_LAYERS.index(name)]
            elif name == "normal":
                layer[rows] = tile.normal
            else:
                layer[rows] = getattr(tile, name)[:, :, None]


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve on values clamped to [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def to_8bit(image: np.ndarray, srgb: bool = False) -> np.ndarray:
    """Display values to uint8: clamp to [0, 1] (never wrap), optional sRGB, round to nearest."""
    values = srgb_encode(image) if srgb else np.clip(image, 0.0, 1.0)
    # NaN would cast to an arbitrary byte; the renderer never produces one, but a caller's array might.
    values = np.nan_to_num(values, nan=0.0)
    return np.round(values * 255.0).astype(np.uint8)
