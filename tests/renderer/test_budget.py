"""renderer/budget.py: the memory estimate's terms (the guard itself: tests/contracts/test_resource_guards.py)."""

from __future__ import annotations

import pytest

import raycast_phong as rp
from raycast_phong.renderer.budget import RAY_BYTES, estimate_memory


@pytest.mark.parametrize("shadow_lights", [0, 2])
def test_every_thread_adds_its_tile_of_rays(shadow_lights):
    """tile_rays × threads rays are in flight at once, each with its shadow rays: a thread more is one
    tile of RAY_BYTES rays more, and nothing else changes."""
    scene = rp.load_scene(rp.default_scene_path())
    tile = 1 << 12
    one, four = (estimate_memory(scene, shadow_lights=shadow_lights, tile_rays=tile, threads=threads)
                 for threads in (1, 4))
    assert four.image - one.image == 3 * tile * (1 + shadow_lights) * RAY_BYTES
    assert (four.geometry, four.triangles) == (one.geometry, one.triangles)
