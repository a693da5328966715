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


def test_a_binary_stl_whose_header_says_solid_is_counted_from_its_header(tmp_path):
    """Exporters often begin a binary STL's 80-byte header with "solid": the file's size, 84 + 50 per triangle,
    tells it from an ASCII one, whose count would otherwise be bounded by its size (86 bytes a facet)."""
    import struct

    from raycast_phong.renderer.budget import mesh_file_triangles
    path = tmp_path / "binary.stl"
    path.write_bytes(b"solid exported".ljust(80, b" ") + struct.pack("<I", 10) + bytes(50 * 10))
    assert mesh_file_triangles(path, "objects.0.path") == 10
