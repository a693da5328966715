"""One primary ray through each pixel-sample centre, straight into Embree's float32 unit frame.

Pixel (column i, row j) with samples = n gets n×n rays through the centres of an n×n grid of cells:
raster (i + (a + ½)/n, j + (b + ½)/n). Row 0 is the top row. Ray k of a tile belongs to pixel k // n²
and sub-cell k % n² (b = row of the cell, a = column).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ...records import Frame
from ...scene.schema import Scene
from .jit import kernel


@dataclass(frozen=True, eq=False)
class CameraRig:
    """An orthonormal camera frame and the half-extent of the image plane at distance 1."""
    eye: np.ndarray        # (3,) float64, world
    right: np.ndarray      # (3,) unit
    up: np.ndarray         # (3,) unit, orthogonal to right and forward
    forward: np.ndarray    # (3,) unit, toward look_at
    half_height: float     # perspective: tan(fov / 2); orthographic: view_height / 2 (world units)
    half_width: float      # half_height × width / height
    orthographic: bool


def camera_rig(scene: Scene) -> CameraRig:
    camera, render = scene.camera, scene.render
    eye = np.asarray(camera.position, np.float64)
    forward = np.asarray(camera.look_at, np.float64) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(camera.up, np.float64))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    orthographic = camera.type == "orthographic"
    half_height = camera.view_height / 2 if orthographic else math.tan(math.radians(camera.fov) / 2)
    return CameraRig(eye, right, up, forward, half_height, half_height * render.width / render.height, orthographic)


class RayParams(NamedTuple):
    """What ray generation needs besides the rows, as one argument for kernels (fill_rows)."""
    width: int
    height: int
    samples: int
    eye: np.ndarray         # (3,) float64, world
    right: np.ndarray
    up: np.ndarray
    forward: np.ndarray
    half_width: float
    half_height: float
    orthographic: bool      # then every ray has its own origin (written); else all start at the eye
    center: np.ndarray      # (3,) the unit frame: unit = (world − center) × inv_scale
    inv_scale: float


class RayGenerator:
    """Primary rays of whole image rows, (N, 3) float32 origins and unit directions in the unit frame.

    A perspective camera's rays all start at the eye: one shared, read-only origins array (Embree
    never writes it) serves every tile, so only directions are computed per tile.
    """

    def __init__(self, rig: CameraRig, frame: Frame, width: int, height: int, samples: int, max_rays: int):
        self.rig, self.frame = rig, frame
        self.width, self.height, self.samples = width, height, samples
        self.params = RayParams(width, height, samples, rig.eye, rig.right, rig.up, rig.forward, rig.half_width,
                                rig.half_height, rig.orthographic, frame.center, 1.0 / frame.scale)
        # (0, 3) for an orthographic camera: kernels take the same argument types either way.
        self.shared_origins = np.zeros((0, 3), np.float32)
        if not rig.orthographic:
            eye = frame.to_unit(rig.eye).astype(np.float32)
            self.shared_origins = np.ascontiguousarray(np.broadcast_to(eye, (max_rays, 3)))

    def rows(self, row0: int, row1: int) -> tuple[np.ndarray, np.ndarray]:
        count = (row1 - row0) * self.width * self.samples * self.samples
        directions = np.empty((count, 3), np.float32)
        if self.rig.orthographic:
            origins = np.empty((count, 3), np.float32)
        else:
            origins = self.shared_origins[:count]
        fill_rows(self.params, row0, row1, origins, directions)
        return origins, directions


def generate_rays(rig: CameraRig, frame: Frame, width: int, height: int, samples: int,
                  row0: int, row1: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays of image rows [row0, row1) (one-off use; render() keeps a RayGenerator)."""
    count = (row1 - row0) * width * samples * samples
    return RayGenerator(rig, frame, width, height, samples, count).rows(row0, row1)


@kernel()
def fill_rows(params, row0, row1, origins, directions):
    """Directions (and, for an orthographic camera, origins) (N, 3) float32 of the rays of rows [row0, row1)."""
    _fill_rays(row0, row1, params.width, params.height, params.samples, params.eye, params.right, params.up,
               params.forward, params.half_width, params.half_height, params.orthographic, params.center,
               params.inv_scale, origins, directions)


@kernel()
def _fill_rays(row0, row1, width, height, samples, eye, right, up, forward, half_width, half_height,
               orthographic, center, inv_scale, origins, directions):
    """Directions (and, for an orthographic camera, origins) of the rays of rows [row0, row1)."""
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
