"""Image differences: a render against a reference, over the pixels both cover.

Coverage (the share of a pixel's samples that hit a surface) separates two kinds of error: pixels
whose coverage differs are counted as the silhouette mismatch and left out of the shading error
(RMSE, max, MAE, PSNR), which is taken over the pixels both images cover fully.
"""

from __future__ import annotations

import math

import numpy as np

from ..records import ImageErrors

PEAK = 1.0            # PSNR's peak signal: display values are meant to lie in [0, 1]
HIGHLIGHT_LEVEL = 0.5  # the specular peak is where the reference's specular term is ≥ half its maximum


def rmse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    """Root mean square of the RGB differences over the (H, W) mask; nan on an empty mask."""
    diff = np.asarray(image, np.float64)[mask] - np.asarray(reference, np.float64)[mask]
    return float(np.sqrt(np.mean(diff ** 2))) if diff.size else math.nan


def psnr(error: float, peak: float = PEAK) -> float:
    """Peak signal-to-noise ratio, 20 log10(peak / rmse) dB; inf when rmse = 0."""
    return math.inf if error == 0 else 20 * math.log10(peak / error)


def silhouette_pixels(coverage: np.ndarray, reference_coverage: np.ndarray) -> int:
    """Pixels covered by one image and not the other, or (with samples > 1) covered by a different share."""
    return int((coverage != reference_coverage).sum())


def highlight_loss(image: np.ndarray, reference: np.ndarray, reference_specular: np.ndarray,
                   mask: np.ndarray) -> float:
    """How much of the reference's specular peak the render misses, 0 (all there) … 1 (none).

    Over the peak P (pixels in `mask` whose reference specular term, summed over RGB, is at least
    HIGHLIGHT_LEVEL of its maximum):  1 − Σ_P clip(render − (reference − specular), 0, specular) / Σ_P specular,
    i.e. the render's light above the reference's non-specular part, each pixel counted at most up to the
    reference's highlight there (overshoot elsewhere does not make up for a missing peak). nan when the
    reference has no highlight in the mask.
    """
    specular = np.asarray(reference_specular, np.float64).sum(axis=-1)
    peak_value = specular[mask].max() if mask.any() else 0.0
    if not peak_value > 0:
        return math.nan
    peak = mask & (specular >= HIGHLIGHT_LEVEL * peak_value)
    base = np.asarray(reference, np.float64).sum(axis=-1) - specular
    delivered = np.clip(np.asarray(image, np.float64).sum(axis=-1) - base, 0, specular)
    return float(1 - delivered[peak].sum() / specular[peak].sum())


def measure(image: np.ndarray, coverage: np.ndarray, reference) -> ImageErrors:
    """All the errors of a render (H, W, 3) with its coverage (H, W) against a ReferenceImage."""
    both = (coverage == 1) & (reference.coverage == 1)
    error = rmse(image, reference.image, both)
    diff = np.abs(np.asarray(image, np.float64)[both] - reference.image[both])
    return ImageErrors(
        rmse=error,
        max_error=float(diff.max()) if diff.size else math.nan,
        psnr=psnr(error) if not math.isnan(error) else math.nan,
        mae=float(diff.mean()) if diff.size else math.nan,
        silhouette_pixels=silhouette_pixels(coverage, reference.coverage),
        highlight_loss=highlight_loss(image, reference.image, reference.specular, both),
        compared_pixels=int(both.sum()),
        reference=reference.kind,
    )
