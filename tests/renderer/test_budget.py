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


# ---------------------------------------------------------------- the refusal as render() applies it
# Renderer.check_fits is prepare()'s plan and memory check alone (render() runs the same _fitted), building nothing.
MiB = 1 << 20


def _checked(scene, budget):
    from raycast_phong.renderer.prepare import Renderer
    return Renderer(threads=1, max_memory=budget).check_fits(scene)


def test_a_large_colour_map_alone_is_refused_under_a_budget_it_exceeds(tmp_path):
    """A 2048² kd_map decodes to 2048² × 52 B (float32 RGB 12, its mip pyramid 16, the level means 24) = 208 MiB,
    while the plane and a 32² image take under 16 MiB: refused at 200 MiB, accepted at 250 MiB. Catches the
    texture term left out of the estimate or of its total (the scene passed at 16 MiB)."""
    from PIL import Image

    from raycast_phong.errors import SceneError
    Image.new("RGB", (2048, 2048), (90, 120, 30)).save(tmp_path / "big.png")
    for name, key in (("plain", ""), ("mapped", 'kd_map = "big.png"\n')):
        (tmp_path / f"{name}.toml").write_text(f'[render]\nwidth = 32\nheight = 32\n[materials.m]\nkd = 0.5\n{key}'
                                               '[[objects]]\nshape = "plane"\nmaterial = "m"\n')
    assert _checked(rp.load_scene(tmp_path / "plain.toml"), 16 * MiB).total < 16 * MiB  # the rest is small
    scene = rp.load_scene(tmp_path / "mapped.toml")
    with pytest.raises(SceneError, match="budget"):
        _checked(scene, 200 * MiB)
    found = _checked(scene, 250 * MiB)
    assert found.textures == 2048 * 2048 * 52 and 208 * MiB < found.total < 224 * MiB


def test_global_mode_s_shadow_rays_are_in_the_estimate_render_checks():
    """Global mode casts a shadow ray per light from every hit: each tile of 2^15 rays (prepare.TILE_RAYS) holds
    1 + lights rays of 64 bytes each, so 9 lights rather than 1 add 8 × 2^15 × 64 B = 16 MiB to the image term.
    Catches prepare() passing no shadow lights to the estimate (the two estimates equal)."""
    def scene(lights):
        return rp.validate_scene({"render": {"width": 64, "height": 64, "mode": "global"},
                                  "lights": [{"type": "point", "position": [k, 5, 5]} for k in range(lights)],
                                  "objects": [{"shape": "plane"}]})
    one, nine = _checked(scene(1), None), _checked(scene(9), None)
    assert nine.image - one.image == 8 * (1 << 15) * 64
    assert nine.image == (1 + 9) * (1 << 15) * 64 + 64 * 64 * (12 + 12)  # rays; float32 RGB film and its copy


def test_global_mode_weighs_the_float64_copy_of_the_corner_normals_of_a_smooth_object():
    """Global mode keeps a float64 copy of the corner normals for its shadow rays' origins (FLOAT64_NORMAL_BYTES a
    triangle), as float64 shading does: a smooth sphere's geometry term grows by exactly that, a flat one's not.
    Catches the copy weighed for float64 shading only."""
    from raycast_phong.renderer.budget import FLOAT64_NORMAL_BYTES, shape_triangles

    def estimate(mode, shading):
        return _checked(rp.validate_scene({"render": {"width": 8, "height": 8, "mode": mode, "shading": shading},
                                           "lights": [{"type": "point", "position": [0, 5, 5]}],
                                           "objects": [{"shape": "icosphere", "subdivisions": 4}]}), None)
    triangles = shape_triangles(rp.validate_scene({"objects": [{"shape": "icosphere", "subdivisions": 4}]}).objects[0])
    grown = estimate("global", "phong").geometry - estimate("local", "phong").geometry
    assert grown == triangles * FLOAT64_NORMAL_BYTES
    assert estimate("global", "flat").geometry == estimate("local", "flat").geometry  # no corner normals to copy


def test_of_two_objects_that_weigh_the_same_the_refusal_names_the_first():
    """Two icospheres of subdivision 8 that differ in their material (two kinds, the same bytes) are refused
    together; the line names the largest by the first of them, objects.0, as documented (the first object of the
    largest kind). Catches a tie given to the later object."""
    from raycast_phong.errors import SceneError
    scene = rp.validate_scene({"materials": {"red": {"kd": [1, 0, 0]}, "blue": {"kd": [0, 0, 1]}},
                               "objects": [{"shape": "icosphere", "subdivisions": 8, "material": "red"},
                                           {"shape": "icosphere", "subdivisions": 8, "material": "blue",
                                            "translate": [3, 0, 0]}]})
    with pytest.raises(SceneError) as refused:
        _checked(scene, 64 * MiB)
    assert "the largest objects.0.subdivisions = 8" in str(refused.value), refused.value


def test_a_large_one_line_obj_costs_its_read_whatever_triangles_it_claims(tmp_path):
    """A 256 MiB OBJ of one comment line (sparse: written in no time) has no face, but reading text costs 12 bytes
    a byte at least (io/meshes/format.py's measurement): 3 GiB, refused under a 2 GiB budget. Catches the read
    floor dropped from the estimate (the scene then weighed 9 MB: the image and one object)."""
    from raycast_phong.errors import SceneError
    path = tmp_path / "one.obj"
    with open(path, "wb") as handle:
        handle.write(b"# one line")
        handle.truncate(256 * MiB)
    scene = rp.validate_scene({"objects": [{"shape": "mesh", "path": str(path)}]})
    with pytest.raises(SceneError, match=r"needs ≈ 3\.01 GB of memory for geometry \(0 triangles\)"):
        _checked(scene, "2G")
    assert estimate_memory(scene).geometry == 256 * MiB * 12 + 2000  # the read floor, and the object's own bytes


def test_a_3mf_s_textures_are_in_the_estimate(tmp_path):
    """A 3MF whose texture2d is a 1024 × 512 PNG in its zip: 1024 × 512 × 52 B = 26 MiB (27.3 MB) of texture term,
    read from the image's header; its thumbnail is not a texture. Catches a texture term of 0 for a 3MF (the
    estimate counted OBJ and glTF maps only)."""
    import io
    import zipfile

    from PIL import Image
    png, thumbnail = io.BytesIO(), io.BytesIO()
    Image.new("RGB", (1024, 512), (200, 10, 10)).save(png, "PNG")
    Image.new("RGB", (256, 256)).save(thumbnail, "PNG")
    model = ('<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" xmlns="http://schemas.microsoft.com/'
             '3dmanufacturing/core/2015/02" xmlns:m="http://schemas.microsoft.com/3dmanufacturing/material/2015/02">'
             '<resources><m:texture2d id="3" path="/3D/Texture/t.png" contenttype="image/png"/>'
             '<m:texture2dgroup id="4" texid="3"><m:tex2coord u="0" v="0"/><m:tex2coord u="1" v="0"/>'
             '<m:tex2coord u="1" v="1"/></m:texture2dgroup><object id="1" type="model"><mesh><vertices>'
             '<vertex x="0" y="0" z="0"/><vertex x="10" y="0" z="0"/><vertex x="10" y="10" z="0"/></vertices>'
             '<triangles><triangle v1="0" v2="1" v3="2" pid="4" p1="0" p2="1" p3="2"/></triangles></mesh></object>'
             '</resources><build><item objectid="1"/></build></model>')
    path = tmp_path / "t.3mf"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model)
        archive.writestr("3D/Texture/t.png", png.getvalue())
        archive.writestr("Metadata/thumbnail.png", thumbnail.getvalue())
    scene = rp.validate_scene({"objects": [{"shape": "mesh", "path": str(path)}]})
    assert estimate_memory(scene).textures == 1024 * 512 * 52
