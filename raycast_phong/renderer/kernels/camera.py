"""One primary ray through each pixel-sample centre, straight into Embree's float32 unit frame (numba;
the camera's RayParams come from renderer/pack.py).

Pixel (column i, row j) with samples = n gets n×n rays through the centres of an n×n grid of cells:
raster (i + (a + ½)/n, j + (b + ½)/n). Row 0 is the top row. Ray k of a tile belongs to pixel k // n²
and sub-cell k % n² (b = row of the cell, a = column). The formulas live here once: fill_rows writes the
rays into arrays, ray_queries.camera_hits straight into Embree's packets, with the same operations (same bits).
"""

from __future__ import annotations

import math

import numpy as np

from ...jit import kernel


@kernel()
def screen_columns(params):
    """Screen x (float64) and cell row b of each ray column c = i n² + b n + a of an image row (width n²
    entries): raster → screen x from -1 (left) to 1, times half_width. Computed once per band: the divisions
    per ray were 40 % of the generation time."""
    width, samples, half_width = params.width, params.samples, params.half_width
    per_pixel = samples * samples
    screen_x = np.empty(width * per_pixel)
    cell_row = np.empty(width * per_pixel, np.int64)
    for col in range(width):
        for b in range(samples):
            for a in range(samples):
                c = col * per_pixel + b * samples + a
                screen_x[c] = (2.0 * (col + (a + 0.5) / samples) / width - 1.0) * half_width
                cell_row[c] = b
    return screen_x, cell_row


@kernel(inline="always")
def screen_y(params, row, b):
    """Screen y of cell row b of image row `row`: from 1 (top) to -1, times half_height."""
    return (1.0 - 2.0 * (row + (b + 0.5) / params.samples) / params.height) * params.half_height


@kernel(inline="always")
def direction(fx, fy, fz, rx, ry, rz, ux, uy, uz, sx, sy):
    """The unit direction forward + sx right + sy up, normalised in float64 (the caller rounds it once)."""
    dx = fx + sx * rx + sy * ux
    dy = fy + sx * ry + sy * uy
    dz = fz + sx * rz + sy * uz
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    return dx / norm, dy / norm, dz / norm


@kernel(inline="always")
def unit_eye(params):
    """The eye in the unit frame, float64: (eye − center) × inv_scale, each coordinate."""
    return ((params.eye[0] - params.center[0]) * params.inv_scale,
            (params.eye[1] - params.center[1]) * params.inv_scale,
            (params.eye[2] - params.center[2]) * params.inv_scale)


@kernel(inline="always")
def ortho_origin(params, i, sx, sy):
    """Coordinate i of an orthographic ray's origin, eye + sx right + sy up, in the unit frame."""
    return (params.eye[i] + sx * params.right[i] + sy * params.up[i] - params.center[i]) * params.inv_scale


@kernel()
def fill_rows(params, row0, row1, origins, directions):
    """Directions (and, for an orthographic camera, origins) (N, 3) float32 of the rays of rows [row0, row1);
    params: layout.RayParams."""
    samples, orthographic = params.samples, params.orthographic
    forward, right, up = params.forward, params.right, params.up
    fx, fy, fz, rx, ry, rz, ux, uy, uz = (forward[0], forward[1], forward[2], right[0], right[1], right[2],
                                          up[0], up[1], up[2])
    screen_x, cell_row = screen_columns(params)
    row_rays = screen_x.shape[0]
    sy_row = np.empty(samples)  # screen y of the row's n cell rows
    k = 0
    for row in range(row0, row1):
        for b in range(samples):
            sy_row[b] = screen_y(params, row, b)
        for c in range(row_rays):
            sx, sy = screen_x[c], sy_row[cell_row[c]]
            if orthographic:
                for i in range(3):
                    origins[k, i] = ortho_origin(params, i, sx, sy)
                    directions[k, i] = forward[i]
            else:
                directions[k, 0], directions[k, 1], directions[k, 2] = direction(fx, fy, fz, rx, ry, rz,
                                                                                 ux, uy, uz, sx, sy)
            k += 1
