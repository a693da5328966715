"""The band kernel's fused ray generation and cast (ray_queries.camera_hits) against the two stages it replaced:
camera.fill_rows into arrays, then ray_queries.intersect_rays on them. Both compute each ray with camera.py's
formulas and cast the same 4 × 4 blocks, so directions and hits must agree bit for bit, for either camera,
any sample count, image sizes that leave partial packets, and bands cut at any row."""

from __future__ import annotations

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.renderer.kernels.camera import fill_rows, screen_columns
from raycast_phong.renderer.kernels.ray_queries import camera_hits, intersect_rays
from raycast_phong.renderer.prepare import prepare


def _scene(camera: str, width: int, height: int, samples: int) -> rp.Scene:
    cam = {"type": "orthographic", "view_height": 2.5} if camera == "orthographic" else {"fov": 50}
    return rp.validate_scene({
        "render": {"width": width, "height": height, "samples": samples},
        "camera": {"position": [0.3, 0.2, 4], "look_at": [0, 0, 0], **cam},
        "lights": [{"type": "point", "position": [2, 2, 3]}],
        "objects": [{"shape": "icosphere", "subdivisions": 3, "radius": 1.0}],
    }, source="test")


def _two_stages(scene_id, params, shared_origins, row0, row1):
    count = (row1 - row0) * params.width * params.samples ** 2
    origins = np.empty((count, 3), np.float32) if params.orthographic else shared_origins[:count]
    directions = np.empty((count, 3), np.float32)
    fill_rows(params, row0, row1, origins, directions)
    hits = [np.empty(count, np.int32), *(np.empty(count, np.float32) for _ in range(3))]
    intersect_rays(scene_id, origins, directions, params.width * params.samples ** 2, *hits)
    return directions, hits


@pytest.mark.parametrize("camera", ["perspective", "orthographic"])
@pytest.mark.parametrize(("width", "height", "samples"), [(37, 23, 1), (18, 11, 2), (7, 9, 3)])
def test_fused_rays_and_hits_are_the_two_stages_bit_for_bit(camera, width, height, samples):
    ready = prepare(_scene(camera, width, height, samples))
    accelerator = ready.build()
    params, shared = ready.rays.params, ready.rays.shared_origins
    # Bands cut mid-packet (a 4-row block split across two calls) and a band of one row.
    for row0, row1 in [(0, height), (0, 5), (5, height - 1), (height - 1, height)]:
        directions, hits = _two_stages(accelerator.embree_scene.scene, params, shared, row0, row1)
        count = len(directions)
        fused = np.full((count, 3), np.nan, np.float32)
        got = [np.full(count, 7, np.int32), *(np.full(count, np.nan, np.float32) for _ in range(3))]
        camera_hits(accelerator.embree_scene.scene, params, *screen_columns(params), row0, row1, shared, fused, *got)
        assert fused.tobytes() == directions.tobytes()
        for ours, theirs in zip(got, hits):
            assert ours.tobytes() == theirs.tobytes()
        if row1 - row0 == height:
            assert (got[0] >= 0).any() and (got[0] < 0).any()  # some rays hit, some miss


def test_no_rows_touch_nothing():
    """A band of no rows (how warm_kernels types the kernel) writes nothing and does not read the eye."""
    ready = prepare(_scene("perspective", 8, 8, 1))
    accelerator = ready.build()
    params = ready.rays.params
    camera_hits(accelerator.embree_scene.scene, params, *screen_columns(params), 3, 3, np.zeros((0, 3), np.float32),
                np.zeros((0, 3), np.float32), np.zeros(0, np.int32), *(np.zeros(0, np.float32) for _ in range(3)))
