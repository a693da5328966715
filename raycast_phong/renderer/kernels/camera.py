"""One primary ray through each pixel-sample centre, straight into Embree's float32 unit frame (numba;
the camera's RayParams come from renderer/pack.py).

Pixel (column i, row j) with samples = n gets n×n rays through the centres of an n×n grid of cells:
raster (i + (a + ½)/n, j + (b + ½)/n). Row 0 is the top row. Ray k of a tile belongs to pixel k // n²
and sub-cell k % n² (b = row of the cell, a = column).
"""

from __future__ import annotations

import math

import numpy as np

from .jit import kernel


@kernel()
def fill_rows(params, row0, row1, origins, directions):
    """Directions (and, for an orthographic camera, origins) (N, 3) float32 of the rays of rows [row0, row1);
    params: layout.RayParams."""
    width, height, samples, orthographic = params.width, params.height, params.samples, params.orthographic
    eye, right, up, forward, center = params.eye, params.right, params.up, params.forward, params.center
    half_width, half_height, inv_scale = params.half_width, params.half_height, params.inv_scale
    # Raster → screen: x from -1 (left) to 1, y from 1 (top) to -1. The screen offsets of the row's columns
    # and of the row's sample rows are computed once, by the same expressions (the same bits) as per ray:
    # their four divisions per ray were 40 % of the generation time.
    screen_x = np.empty(width * samples)
    for col in range(width):
        for a in range(samples):
            screen_x[col * samples + a] = (2.0 * (col + (a + 0.5) / samples) / width - 1.0) * half_width
    screen_y = np.empty(samples)
    k = 0
    for row in range(row0, row1):
        for b in range(samples):
            screen_y[b] = (1.0 - 2.0 * (row + (b + 0.5) / samples) / height) * half_height
        for col in range(width):
            for b in range(samples):
                sy = screen_y[b]
                for a in range(samples):
                    sx = screen_x[col * samples + a]
                    if orthographic:
                        for i in range(3):
                            origins[k, i] = (eye[i] + sx * right[i] + sy * up[i] - center[i]) * inv_scale
                            directions[k, i] = forward[i]
                    else:
                        dx = forward[0] + sx * right[0] + sy * up[0]
                        dy = forward[1] + sx * right[1] + sy * up[1]
                        dz = forward[2] + sx * right[2] + sy * up[2]
                        norm = math.sqrt(dx * dx + dy * dy + dz * dz)  # normalise in float64, then round once
                        directions[k, 0], directions[k, 1], directions[k, 2] = dx / norm, dy / norm, dz / norm
                    k += 1
