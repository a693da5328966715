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
# Renderer.check_fits is prepare()'s plan and memory check alone (render() runs the same fit.fitted), building nothing.
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


# ---------------------------------------------------------------- the estimate's boundaries, exactly
# Each test below feeds the exact input at which a comparison or a term of the estimate decides, so that `<` for
# `<=`, a limit one off or a dropped term changes what it asserts.


def test_a_budget_exactly_met_is_accepted_and_one_byte_less_is_refused():
    """The budget is what the render may use: an estimate equal to it fits, one byte over does not."""
    from raycast_phong.errors import SceneError
    from raycast_phong.renderer.budget import check_memory
    scene = rp.validate_scene({"objects": [{"shape": "icosphere", "subdivisions": 3}]})
    need = estimate_memory(scene).total
    assert check_memory(scene, need).total == need
    with pytest.raises(SceneError, match="budget"):
        check_memory(scene, need - 1)


def test_a_mesh_file_at_crease_angle_180_is_weighed_uncreased_with_its_parse(tmp_path):
    """crease_angle 180 creases nothing: a smooth mesh file costs SMOOTH_BYTES plus its format's parse bytes a
    triangle; just under 180 every corner may take the pairwise test (CREASED_FILE_BYTES). The 1,280 triangles'
    cost is above the file's read floor, so the per-triangle figure decides."""
    import trimesh

    from raycast_phong.io.meshes.source import mesh_source
    from raycast_phong.renderer.budget import CREASED_FILE_BYTES, OBJECT_BYTES, SMOOTH_BYTES
    trimesh.creation.icosphere(subdivisions=3).export(tmp_path / "ball.ply")
    source = mesh_source(tmp_path / "ball.ply")
    count, parse = source.triangles(), source.format.parse_bytes
    assert count == 1280 and parse > 0 and source.read_floor() < count * SMOOTH_BYTES

    def geometry(angle):
        return estimate_memory(rp.validate_scene({"objects": [{"shape": "mesh", "path": str(tmp_path / "ball.ply"),
                                                               "crease_angle": angle}]})).geometry
    assert geometry(180) == count * (SMOOTH_BYTES + parse) + OBJECT_BYTES
    assert geometry(179.5) == count * (CREASED_FILE_BYTES + parse) + OBJECT_BYTES


def test_the_morton_saving_starts_at_exactly_morton_faces_triangles():
    """Embree's Morton build (MORTON_SAVING_BYTES less a triangle) starts at MORTON_FACES triangles in all: a plane
    of 256 × 512 segments makes exactly 2^18 of them and saves; 256 × 511 is one row short and does not."""
    from raycast_phong.renderer.budget import FLAT_BYTES, MORTON_SAVING_BYTES, OBJECT_BYTES
    from raycast_phong.renderer.embree_library import MORTON_FACES

    def found(rows):
        return estimate_memory(rp.validate_scene({"objects": [{"shape": "plane", "segments": [256, rows]}]}),
                               smooth=False)
    assert found(512).triangles == MORTON_FACES
    assert found(512).geometry == MORTON_FACES * (FLAT_BYTES - MORTON_SAVING_BYTES) + OBJECT_BYTES
    assert found(511).geometry == 2 * 256 * 511 * FLAT_BYTES + OBJECT_BYTES


def test_every_term_of_the_image_estimate_in_float32_and_float64():
    """The image term of a 10 × 10 render with a term layer, a normal and a face layer: the film (RGB and 4 terms
    × 3 channels at 4 or 8 bytes, 20 bytes of geometry layers), one float32 copy of each channel written (RGB, 2
    × 3, 1) and 2^15 rays of 64 bytes (the default tile, one thread, no shadow rays); no texture, so 0."""
    scene = rp.validate_scene({"render": {"width": 10, "height": 10},
                               "output": {"aovs": ["diffuse", "normal", "face"]}, "objects": [{"shape": "box"}]})
    written, rays = 100 * 4 * (3 + 6 + 1), (1 << 15) * 64
    for real, float64 in ((4, False), (8, True)):
        found = estimate_memory(scene, float64=float64)
        assert found.image == 100 * (3 * real + 12 * real + 20) + written + rays, real
        assert found.textures == 0 and found.total == found.geometry + found.image


def test_the_refusal_at_geometry_equal_to_image_blames_the_geometry():
    """A flat plane of 3 × 10 segments (60 triangles, 18,200 B with its object) on a 1 × 1 image with 284 rays in
    flight (24 + 284 × 64 = 18,200 B): the two parts tie and the line names the object's key, with the image's
    share since it is more than a twentieth."""
    from raycast_phong.errors import SceneError
    from raycast_phong.renderer.budget import check_memory
    scene = rp.validate_scene({"render": {"width": 1, "height": 1},
                               "objects": [{"shape": "plane", "segments": [3, 10]}]})
    options = {"smooth": False, "tile_rays": 284}
    found = estimate_memory(scene, **options)
    assert found.geometry == found.image == 18_200
    with pytest.raises(SceneError) as refused:
        check_memory(scene, 1000, **options)
    assert "objects.0.segments: [3, 10] needs ≈ " in str(refused.value), refused.value
    assert "for the image" in str(refused.value)


def test_an_image_of_exactly_a_twentieth_of_the_total_is_not_named():
    """The image's bytes join a geometry refusal only above a twentieth of the total: a flat plane of 10 × 13
    segments (72,200 B) on a 1 × 1 image with 59 rays (3,800 B = 76,000 / 20) is at the limit, not above it."""
    from raycast_phong.errors import SceneError
    from raycast_phong.renderer.budget import check_memory
    scene = rp.validate_scene({"render": {"width": 1, "height": 1},
                               "objects": [{"shape": "plane", "segments": [10, 13]}]})
    options = {"smooth": False, "tile_rays": 59}
    found = estimate_memory(scene, **options)
    assert (found.geometry, found.image) == (72_200, 3_800)
    with pytest.raises(SceneError) as refused:
        check_memory(scene, 1000, **options)
    assert "objects.0.segments: [10, 13] needs ≈ " in str(refused.value), refused.value
    assert "for the image" not in str(refused.value)


def test_an_object_of_exactly_half_the_geometry_is_named_by_its_key():
    """One object is named alone when it weighs half the geometry or more: in float64, a smooth plane of 4 × 5
    segments (40 × 370 = 14,800 B) beside a flat one (40 × 270 = 10,800 B) and their 2 × 2,000 B objects is
    exactly half of 29,600 B."""
    from raycast_phong.errors import SceneError
    from raycast_phong.renderer.budget import check_memory
    scene = rp.validate_scene({"render": {"width": 1, "height": 1},
                               "objects": [{"shape": "plane", "segments": [4, 5]},
                                           {"shape": "plane", "segments": [4, 5], "shading": "flat"}]})
    options = {"float64": True, "tile_rays": 0}
    found = estimate_memory(scene, **options)
    assert (found.largest, 2 * found.largest_bytes, found.geometry) == (0, 29_600, 29_600)
    with pytest.raises(SceneError) as refused:
        check_memory(scene, 1000, **options)
    assert "objects.0.segments: [4, 5] needs ≈ " in str(refused.value), refused.value


@pytest.mark.parametrize("samples, shown", [(1, None), (2, ", 2² samples")])
def test_an_image_refusal_names_the_samples_only_above_one(samples, shown):
    """A 2000 × 2000 image of a box under a 1 MB budget is refused naming the pixels; one sample a pixel is the
    default and goes unsaid."""
    from raycast_phong.errors import SceneError
    from raycast_phong.renderer.budget import check_memory
    scene = rp.validate_scene({"render": {"width": 2000, "height": 2000, "samples": samples},
                               "objects": [{"shape": "box"}]})
    with pytest.raises(SceneError) as refused:
        check_memory(scene, 1 << 20)
    message = str(refused.value)
    assert "render.width × render.height: 2000×2000 pixels" in message
    assert ("samples" not in message) if shown is None else (shown in message), message


def test_only_the_maps_of_used_materials_and_of_default_are_weighed(tmp_path):
    """A colour map counts when its material is used or is "default" (what a mesh file's faces without a
    material take); an unused material's map costs nothing."""
    from PIL import Image
    colour = str(tmp_path / "map.png")
    Image.new("RGB", (64, 64)).save(colour)

    def textures(materials):
        return estimate_memory(rp.validate_scene({"materials": materials,
                                                  "objects": [{"shape": "box", "material": "used"}]})).textures
    plain = {"used": {"kd": 0.5}}
    assert textures({**plain, "spare": {"kd_map": colour}}) == 0
    assert textures({**plain, "default": {"kd_map": colour}}) > 0
    assert textures({"used": {"kd_map": colour}}) > 0


def test_an_empty_mesh_file_over_the_budget_is_refused_naming_it(tmp_path):
    """An empty OBJ weighs nothing (no triangle, no read floor) but its object's OBJECT_BYTES: the largest object
    is still the first, at 0 bytes, and the refusal names its path rather than failing to find one."""
    from raycast_phong.errors import SceneError
    from raycast_phong.renderer.budget import OBJECT_BYTES, check_memory
    (tmp_path / "empty.obj").write_bytes(b"")
    scene = rp.validate_scene({"render": {"width": 1, "height": 1},
                               "objects": [{"shape": "mesh", "path": str(tmp_path / "empty.obj")}]})
    found = estimate_memory(scene, tile_rays=0)
    assert (found.triangles, found.geometry, found.largest, found.largest_bytes) == (0, OBJECT_BYTES, 0, 0)
    with pytest.raises(SceneError, match=r"the largest objects\.0\.path = '.*empty\.obj'"):
        check_memory(scene, 100, tile_rays=0)
