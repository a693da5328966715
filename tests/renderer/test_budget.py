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

    from raycast_phong.io.meshes.source import mesh_source
    path = tmp_path / "binary.stl"
    path.write_bytes(b"solid exported".ljust(80, b" ") + struct.pack("<I", 10) + bytes(50 * 10))
    assert mesh_source(path).triangles() == 10


def test_every_object_adds_its_own_bytes_whatever_its_triangles():
    """An object costs OBJECT_BYTES besides its triangles (its validated Object, its geometry rows): 10,000
    planes of 2 triangles are 10,000 × (2 × FLAT_BYTES + OBJECT_BYTES) bytes of geometry."""
    from raycast_phong.renderer.budget import FLAT_BYTES, OBJECT_BYTES
    planes = [{"shape": "plane", "size": [0.1, 0.1], "translate": [i, 0, 0]} for i in range(10_000)]
    found = estimate_memory(rp.validate_scene({"objects": planes}), smooth=False)
    assert found.triangles == 20_000
    assert found.geometry == 10_000 * (2 * FLAT_BYTES + OBJECT_BYTES)


MEASURE_MANY_PLANES = """
import sys
import raycast_phong as rp
from raycast_phong.renderer.budget import estimate_memory
def status(field):
    with open("/proc/self/status") as lines:
        return next(int(line.split()[1]) << 10 for line in lines if line.startswith(field))
table = lambda count: {"render": {"width": 64, "height": 48}, "camera": {"position": [50, 50, 400]},
                       "lights": [{"type": "point", "position": [0, 0, 300]}],
                       "objects": [{"shape": "plane", "size": [0.5, 0.5], "rotate": [90, 0, i % 360],
                                    "translate": [i % 100, i // 100, 0]} for i in range(count)]}
rp.render(rp.validate_scene(table(4)))  # kernels loaded, caches warm
many = table(int(sys.argv[1]))
with open("/proc/self/clear_refs", "w") as refs:
    refs.write("5")
start = status("VmRSS:")
scene = rp.validate_scene(many)
estimate = estimate_memory(scene, smooth=True)
rp.render(scene)
print(status("VmHWM:") - start, estimate.total)
"""


def test_many_small_objects_stay_within_the_estimate():
    """Validating and rendering 30,000 planes of 2 triangles peaks below the estimate (measured with VmHWM
    reset after warm-up, in a fresh process): before the per-object term the estimate counted 60,000 triangles
    and the image, about a third of the 40 MB the objects take."""
    import subprocess
    import sys
    done = subprocess.run([sys.executable, "-c", MEASURE_MANY_PLANES, "30000"], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    peak, estimate = map(int, done.stdout.split())
    assert peak <= estimate, f"peak {peak / 2**20:.0f} MB above the estimate {estimate / 2**20:.0f} MB"
