"""The (H, W, 3) image and its layers that tiles are shaded into (their 8-bit encoding is io.encoding's)."""

from __future__ import annotations

import numpy as np

from ..codes import GEOMETRY_LAYERS, TERM_LAYERS
from ..records import ImageBuffers


def allocate_film(width: int, height: int, aovs: tuple[str, ...], dtype: type = np.float32) -> ImageBuffers:
    """Zeroed buffers for the image and only the layers asked for; the image and term layers in
    `dtype` (the shading precision, so a float64 render keeps its digits), the others float32."""
    terms = any(name in TERM_LAYERS for name in aovs)
    geometry = any(name in GEOMETRY_LAYERS for name in aovs)
    h, w = (height, width) if geometry else (0, 0)
    return ImageBuffers(
        rgb=np.zeros((height, width, 3), dtype),
        terms=np.zeros((height, width, 4, 3) if terms else (0, 0, 4, 3), dtype),
        depth=np.full((h, w), np.inf, np.float32),
        normal=np.zeros((h, w, 3), np.float32),
        face=np.full((h, w), -1.0, np.float32),
    )


def film_layers(film: ImageBuffers, aovs: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The requested layers as name → (H, W, C) float32, in the order asked for."""
    return {name: (film.terms[:, :, TERM_LAYERS.index(name)] if name in TERM_LAYERS
                   else film.normal if name == "normal" else getattr(film, name)[:, :, None]) for name in aovs}
