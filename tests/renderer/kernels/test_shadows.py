"""Global mode: shadow rays against analytic shadows, at every scale, with and without the terminator fix."""

import math

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.codes import StageName
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer.intersect import Accelerator, unit_frame
from raycast_phong.renderer.kernels.shadows import cast_shadows
from raycast_phong.renderer.pack import prepare_shadows

MATTE = {"ka": 1.0, "kd": 0.8, "ks": 0.0}


def light_visibility(inputs, hits, directions, accelerator, row_rays: int = 4) -> np.ndarray:
    """(N,) int64 light bits of a tile's hits from the kernel the tile kernel runs (shadows.cast_shadows)."""
    visible = np.empty(len(hits.face), np.int64)
    cast = cast_shadows(accelerator.embree_scene.scene, inputs, hits.face, hits.u, hits.v, directions, row_rays,
                        visible)
    assert cast == (hits.face >= 0).sum() * len(inputs.light_kind)  # one shadow ray per hit and light
    return visible


def test_shadow_packets_in_image_blocks_answer_as_in_scanline_order():
    """cast_shadows takes the hits in 4 × 4 blocks of the image (row_rays wide) to fill its packets; with
    row_rays = 1 they go in ray order. Each ray's answer is its own: the bits must not depend on the grouping,
    for a width that leaves partial blocks and two lights."""
    width, height = 45, 30
    scene = rp.validate_scene({
        "render": {"width": width, "height": height, "mode": "global", "shading": "phong"},
        "camera": {"position": [0, 2, 4], "look_at": [0, 0, 0], "fov": 50},
        "lights": [{"type": "point", "position": [1, 3, 1]}, {"type": "directional", "direction": [-1, -1, 0]}],
        "materials": {"m": MATTE},
        "objects": [{"shape": "plane", "size": [4, 4], "material": "m"},
                    {"shape": "icosphere", "subdivisions": 3, "radius": 0.6, "translate": [0, 0.6, 0],
                     "material": "m"}],
    }, source="test")
    from raycast_phong.renderer.pack import camera_rig, generate_rays
    geometry = build_geometry(scene)
    frame = unit_frame(geometry.vertices)
    accelerator = Accelerator(geometry, frame)
    origins, directions = generate_rays(camera_rig(scene), frame, width, height, 1, 0, height)
    hits = accelerator.closest_hits(origins, directions, width)
    inputs = prepare_shadows(scene, geometry, frame)
    blocks = light_visibility(inputs, hits, directions, accelerator, row_rays=width)
    in_order = light_visibility(inputs, hits, directions, accelerator, row_rays=1)
    assert (blocks == in_order).all()
    assert len(set(blocks[hits.face >= 0].tolist())) == 4  # lit by both, either, neither: all four occur


def test_sphere_over_a_plane_casts_the_analytic_disc():
    """Light straight above a sphere (radius r, centre height h) over the plane y = 0, light at height H:
    the tangent cone has half-angle asin(r / (H − h)), so the shadow is a disc of radius
    R = H · tan(asin(r / (H − h))). Its rendered edge must lie within one pixel of R."""
    r, h, H = 0.5, 1.0, 3.0
    radius = H * math.tan(math.asin(r / (H - h)))
    size, view = 241, 2.4
    pixel = view / size
    scene = rp.validate_scene({
        "render": {"width": size, "height": size, "mode": "global", "shading": "flat", "viewer": "infinite"},
        "camera": {"type": "orthographic", "position": [0, 10, 0], "look_at": [0, 0, 0], "up": [0, 0, -1],
                   "view_height": view},
        "ambient": 0.1,
        "lights": [{"type": "point", "position": [0, H, 0], "specular": 0}],
        "materials": {"m": MATTE},
        "objects": [{"shape": "plane", "size": [4, 4], "material": "m"},
                    {"shape": "icosphere", "subdivisions": 5, "radius": r, "translate": [0, h, 0], "material": "m"}],
        "output": {"path": "x.exr", "aovs": ["face"]},
    })
    result = rp.render(scene)
    plane = result.aovs["face"][..., 0] < 2  # the plane's two faces come first
    centre = (np.arange(size) + 0.5) * pixel - view / 2
    x, z = np.meshgrid(centre, centre)
    distance = np.hypot(x, z)
    shadowed = result.image[..., 0] < 0.1 + 1e-6  # only the ambient term is left
    assert plane[distance < r * 0.9].sum() == 0  # the sphere hides the disc's middle from the camera
    ring = plane & (distance < radius - pixel)
    outside = plane & (distance > radius + pixel)
    assert ring.sum() > 200 and shadowed[ring].all()
    assert outside.sum() > 1000 and not shadowed[outside].any()


@pytest.mark.parametrize("scale", [1e-4, 1.0, 1e4, 1e6])
@pytest.mark.parametrize("far", [False, True])
def test_no_acne_on_a_lit_sphere_at_any_scale(scale, far):
    """Flat-shaded convex sphere, one light to the side: every face that faces the light must see it,
    so global mode equals local mode pixel for pixel (a face turned away is dark in both)."""
    shift = 1e6 * scale if far else 0.0

    def place(p):
        return [scale * c + shift for c in p]

    base = {
        "render": {"width": 64, "height": 64, "shading": "flat"},
        "camera": {"position": place([0.5, 0.3, 4]), "look_at": place([0, 0, 0]), "fov": 40},
        "lights": [{"type": "point", "position": place([3, 1, 1])}],
        "materials": {"m": {"ka": 1, "kd": 0.8, "ks": 0.5}},
        "objects": [{"shape": "icosphere", "subdivisions": 3, "radius": scale, "translate": place([0, 0, 0]),
                     "material": "m"}],
    }
    local = rp.render(rp.validate_scene(base)).image
    shadowed = rp.render(rp.validate_scene({**base, "render": {**base["render"], "mode": "global"}})).image
    assert local.max() > 0.5
    np.testing.assert_array_equal(shadowed, local)


@pytest.mark.parametrize("scale", [1e-4, 1.0, 1e4, 1e6])
@pytest.mark.parametrize("far", [False, True])
def test_no_light_leaks_under_an_occluder_1e4_of_the_scene_size_above_a_plane(scale, far):
    """A square lid hovers 1e-4 × the scene size over a plane, the light straight above: points of the
    plane under the lid are in shadow, points beyond it are lit. Queried directly with shadow rays from
    the plane, seen from below (so the lid does not hide them from the camera)."""
    shift = 1e6 * scale if far else 0.0
    gap = 1e-4 * 2 * scale  # the scene is 2 × scale across
    scene = rp.validate_scene({
        "render": {"width": 32, "height": 32, "mode": "global"},
        "camera": {"type": "orthographic", "position": [shift, shift - 5 * scale, shift], "look_at": [shift] * 3,
                   "up": [0, 0, 1], "view_height": 1.8 * scale},
        "lights": [{"type": "point", "position": [shift, shift + 10 * scale, shift]}],
        "objects": [{"shape": "plane", "size": [2 * scale, 2 * scale], "segments": [4, 4], "translate": [shift] * 3},
                    {"shape": "plane", "size": [scale, scale], "translate": [shift, shift + gap, shift]}],
    })
    geometry = build_geometry(scene)
    frame = unit_frame(geometry.vertices)
    accelerator = Accelerator(geometry, frame)
    from raycast_phong.renderer.pack import RayGenerator, camera_rig
    origins, directions = RayGenerator(camera_rig(scene), frame, 32, 32, 1, 32 * 32).rows(0, 32)
    hits = accelerator.closest_hits(origins, directions)
    assert (hits.face >= 0).all() and (hits.face < 32).all()  # every ray sees the big plane from below
    visible = light_visibility(prepare_shadows(scene, geometry, frame), hits, directions, accelerator)
    position = (origins + hits.t[:, None] * directions) * frame.scale + frame.center  # world, for labels only
    under = np.all(np.abs(position[:, [0, 2]] - shift) < 0.45 * scale, axis=1)
    beyond = np.any(np.abs(position[:, [0, 2]] - shift) > 0.55 * scale, axis=1)
    assert under.sum() > 100 and beyond.sum() > 100
    assert (visible[under] == 0).all(), "light leaks under the lid"
    assert (visible[beyond] == 1).all(), "the plane shadows itself"


def terminator_scene(subdivisions: int, terminator: str, mode: str = "global"):
    return rp.validate_scene({
        "render": {"width": 96, "height": 96, "shading": "phong", "mode": mode, "terminator": terminator},
        "camera": {"position": [0, 0, 4], "fov": 40},
        "ambient": 0.1,
        # Lit from the side, so the terminator crosses the middle of the view.
        "lights": [{"type": "directional", "direction": [-1, 0, -0.15], "specular": 0}],
        "materials": {"m": MATTE},
        "objects": [{"shape": "icosphere", "subdivisions": subdivisions, "material": "m"}],
    })


def self_shadowed_share(subdivisions: int, terminator: str) -> float:
    """Share of the pixels lit in local mode (n·l > 0) that global mode puts in shadow."""
    local = rp.render(terminator_scene(subdivisions, terminator, "local")).image
    shadowed = rp.render(terminator_scene(subdivisions, terminator)).image
    lit = local[..., 0] > 0.1 + 1e-6
    return float((np.abs(shadowed - local).max(axis=2)[lit] > 1e-6).mean())


@pytest.mark.parametrize("subdivisions", [1, 2, 3])
def test_hanika_removes_the_shadow_terminator(subdivisions):
    assert self_shadowed_share(subdivisions, "none") > 0  # the artefact exists, so the test can fail
    assert self_shadowed_share(subdivisions, "hanika") == 0


def two_light_scene(**render):
    """A lid over a plane, a red light from the left and a green one from the right (directional)."""
    return rp.validate_scene({
        "render": {"width": 120, "height": 60, "mode": "global", "shading": "flat", "viewer": "infinite", **render},
        "camera": {"type": "orthographic", "position": [0, 10, 0], "up": [0, 0, -1], "view_height": 3},
        "ambient": 0.0,
        "lights": [{"type": "directional", "direction": [1, -1, 0], "diffuse": [1, 0, 0], "specular": 0},
                   {"type": "directional", "direction": [-1, -1, 0], "diffuse": [0, 1, 0], "specular": 0}],
        "materials": {"m": {"ka": 0, "kd": 0.5, "ks": 0}},
        "objects": [{"shape": "plane", "size": [8, 8], "material": "m"},
                    {"shape": "box", "size": [0.5, 0.5, 4], "translate": [0, 1, 0], "crease_angle": 30,
                     "material": "m"}],
    })


def test_each_light_casts_its_own_shadow_and_colours_mix_in_half_shadow():
    """Plane pixels: lit by both (k_d · cos 45° in red and green) or, in one light's shadow, by the other only."""
    image = rp.render(two_light_scene()).image
    both = np.array([0.5, 0.5, 0]) * math.cos(math.radians(45))
    only_red, only_green = both * [1, 0, 0], both * [0, 1, 0]
    # The box (0.75 to 1.25 over the plane, x in ±0.25): the ray from plane point x toward the red light
    # (which travels +x, so lies up and to the left) is at x − y at height y, inside the box for x in
    # [0.5, 1.5]; the green light's shadow is the mirror image. Elsewhere, and on the box top, both light.
    x = (np.arange(120) + 0.5) / 120 * 6 - 3
    middle = image[30]
    for region, expected in (((x > 0.55) & (x < 1.45), only_green), ((x < -0.55) & (x > -1.45), only_red),
                             (np.abs(x) > 1.55, both), ((np.abs(x) > 0.3) & (np.abs(x) < 0.45), both),
                             (np.abs(x) < 0.2, both)):
        assert region.sum() >= 2
        np.testing.assert_allclose(middle[region], np.tile(expected, (region.sum(), 1)), atol=1e-6)


@pytest.mark.parametrize("shading", ["flat", "gouraud", "phong"])
def test_visibility_is_applied_for_every_shading_model(shading):
    image = rp.render(two_light_scene(shading=shading)).image
    reference = rp.render(two_light_scene()).image
    np.testing.assert_allclose(image, reference, atol=1e-6)  # flat plane and box: all models agree


def test_local_mode_casts_no_shadow_rays():
    """The tile kernel counts the shadow rays it casts: none in local mode, and (the same probe, the positive
    control) one per hit and light in global mode."""
    local, shadowed = two_light_scene(mode="local"), two_light_scene()
    assert not rp.build_plan(local).keeps(StageName.SHADOW_RAYS)
    assert rp.build_plan(shadowed).keeps(StageName.SHADOW_RAYS)
    assert rp.render(local).counts["shadow_rays"] == 0
    # The 8 × 8 plane fills the 6 × 3 view: every pixel is a hit, with a shadow ray to each of 2 lights.
    assert rp.render(shadowed).counts["shadow_rays"] == 120 * 60 * 2


def test_without_the_offset_a_lit_sphere_shadows_itself():
    """The offset is what prevents acne: with offset_scale = 0 many lit pixels see their own face."""
    scene = rp.validate_scene({
        "render": {"width": 48, "height": 48, "mode": "global", "shading": "flat"},
        "lights": [{"type": "point", "position": [3, 1, 1]}],
        "objects": [{"shape": "icosphere", "subdivisions": 3}],
    })
    geometry = build_geometry(scene)
    frame = unit_frame(geometry.vertices)
    accelerator = Accelerator(geometry, frame)
    from raycast_phong.renderer.pack import RayGenerator, camera_rig
    origins, directions = RayGenerator(camera_rig(scene), frame, 48, 48, 1, 48 * 48).rows(0, 48)
    hits = accelerator.closest_hits(origins, directions)
    hit = hits.face >= 0
    centroid = geometry.vertices[geometry.faces[hits.face]].mean(axis=1)
    to_light = np.array([3.0, 1, 1]) - centroid
    to_light /= np.linalg.norm(to_light, axis=1, keepdims=True)
    lit_side = hit & (np.einsum("ij,ij->i", geometry.face_normals[hits.face], to_light) > 0.05)
    assert lit_side.sum() > 100
    with_offset = light_visibility(prepare_shadows(scene, geometry, frame), hits, directions, accelerator)
    without = light_visibility(prepare_shadows(scene, geometry, frame, offset_scale=0.0), hits, directions, accelerator)
    assert (with_offset[lit_side] == 1).all()
    assert (without[lit_side] == 0).mean() > 0.05


def test_global_mode_refuses_more_lights_than_its_bit_masks_hold():
    scene = rp.validate_scene({
        "render": {"width": 8, "height": 8, "mode": "global"},
        "lights": [{"type": "point", "position": [i, 2, 3]} for i in range(64)],
        "objects": [{"shape": "icosphere", "subdivisions": 1}],
    })
    with pytest.raises(rp.SceneError, match="at most 63 lights"):
        rp.render(scene)


def test_global_mode_renders_exactly_as_many_lights_as_its_bit_masks_hold():
    """63 lights, the most an int64 mask of visibility bits holds, render in global mode (the test above takes 64).
    Catches the limit checked with `>=` or moved down by one, which would refuse a scene the docs allow."""
    scene = rp.validate_scene({
        "render": {"width": 4, "height": 4, "mode": "global"},
        "lights": [{"type": "point", "position": [i, 2, 3], "diffuse": 0.01, "specular": 0} for i in range(63)],
        "objects": [{"shape": "icosphere", "subdivisions": 0}],
    })
    assert np.isfinite(rp.render(scene).image).all()


# A point light off to one side between a plane and a second sphere: sphere A (below the light) shadows
# the plane; sphere B (above the light) must not, as shadow rays stop at a point light. The light sits
# below the centre of the scene's box (y 0 to 3.3, centre 1.65), so its position read as a vector from
# that centre points down, away from the plane, while the true direction from the plane points up.
LIGHT_AT = np.array([1.2, 1.6, -0.6])
SPHERES = ((np.array([0.3, 0.8, 0.4]), 0.4), (np.array([1.2, 2.7, -0.6]), 0.6))


def segment_distance(points: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Distance from `centre` to each segment point → LIGHT_AT."""
    along = LIGHT_AT - points
    s = np.clip(np.einsum("ij,ij->i", centre - points, along) / np.einsum("ij,ij->i", along, along), 0, 1)
    return np.linalg.norm(points + s[:, None] * along - centre, axis=1)


def test_a_point_light_shadow_is_where_the_segment_to_the_light_meets_the_sphere():
    """Plane y = 0 seen straight down (orthographic, so pixel (i, j) shows the point under its centre).
    A plane point is in shadow iff the segment from it to the light meets an occluder: computed per pixel
    against the exact spheres, with the icosphere between its inscribed radius and r. A shadow ray cast
    toward the light's position as if it were a direction, from the wrong point, or past the light
    (sphere B would then shadow a ring around the point under the light) fails."""
    size, view = 160, 6.0
    objects = [{"shape": "plane", "size": [8, 8], "material": "m"}]
    objects += [{"shape": "icosphere", "subdivisions": 4, "radius": r, "translate": c.tolist(), "material": "m"}
                for c, r in SPHERES]
    scene = rp.validate_scene({
        "render": {"width": size, "height": size, "mode": "global", "shading": "flat", "viewer": "infinite"},
        "camera": {"type": "orthographic", "position": [0, 10, 0], "look_at": [0, 0, 0], "up": [0, 0, -1],
                   "view_height": view},
        "ambient": 0.1,
        "lights": [{"type": "point", "position": LIGHT_AT.tolist(), "specular": 0}],
        "materials": {"m": MATTE},
        "objects": objects,
        "output": {"path": "x.exr", "aovs": ["face"]},
    })
    result = rp.render(scene)
    geometry = build_geometry(scene)
    plane = (result.aovs["face"][..., 0] >= 0) & (result.aovs["face"][..., 0] < 2)  # the plane's two faces
    # Camera right = forward × up = (0, −1, 0) × (0, 0, −1) = (1, 0, 0); image up = −z, so row j is at z = +centre.
    centre = (np.arange(size) + 0.5) / size * view - view / 2
    x, z = np.meshgrid(centre, centre)
    points = np.stack([x, np.zeros_like(x), z], axis=-1)[plane]
    # Flat shading lights each plane face at its centroid, n·l ≥ 1.6 / |light − farthest corner| ≥ 0.22,
    # × kd 0.8: a lit pixel exceeds the ambient 0.1 by ≥ 0.18; a shadowed one keeps the ambient only.
    shadowed = result.image[..., 0][plane] < 0.1 + 1e-6
    assert (result.image[..., 0][plane][~shadowed] > 0.1 + 0.17).all()
    blocked = np.zeros(len(points), bool)
    clear = np.ones(len(points), bool)
    for index, (c, r) in enumerate(SPHERES):
        faces = geometry.face_object == index + 1
        v0 = geometry.vertices[geometry.faces[faces, 0]]
        r_in = np.min(np.einsum("ij,ij->i", v0 - c, geometry.face_normals[faces]))
        distance = segment_distance(points, c)
        blocked |= distance < r_in - 1e-4    # 1e-4: the offset origin, 256 float32 ulps of a ~3-unit scene
        clear &= distance > r + 1e-4
    assert blocked.sum() > 500 and clear.sum() > 5000
    assert shadowed[blocked].all(), "a point whose segment to the light meets a sphere is lit"
    assert not shadowed[clear].any(), "a point that sees the light is in shadow"
    # Where sphere B lies on the ray from the point on past the light, the point is lit all the same:
    # a shadow ray that ran on past the light would darken this disc under the light.
    c, r = SPHERES[1]
    along = LIGHT_AT - points
    s = np.einsum("ij,ij->i", c - points, along) / np.einsum("ij,ij->i", along, along)  # > 1: past the light
    behind_light = np.linalg.norm(points + s[:, None] * along - c, axis=1) < r - 0.05
    assert (behind_light & clear).sum() > 500


@pytest.mark.parametrize("from_below", [False, True])
@pytest.mark.parametrize("weights", [(0.2, 0.3, 0.5), (0.6, 0.1, 0.3), (1 / 3, 1 / 3, 1 / 3)])
def test_hanika_origin_is_the_mean_of_the_corners_tangent_plane_points(weights, from_below):
    """Hanika 2021, as written in the paper: p' = Σ_j b_j (v_j + t_j), t_j = (p − v_j) minus its part below
    corner j's tangent plane, min(0, (p − v_j)·n_j) n_j. One triangle in the unit frame, corner normals
    tilted 30° outward (a bulge of ~0.1), a light straight above: the shadow ray's origin is p' plus the
    offset along +z, 8 float32 roundings (2^-24) of the largest coordinate of the corners and of p' (1 here),
    each to the float32 rounding of the stored origin (2 ulps of 0.6: 1.2e-7). Seen from below with two-sided
    shading (light below too, normals tilted inward so the back is the convex side), every normal turns
    over and the surface bulges downward."""
    from raycast_phong.renderer.kernels.layout import ShadowInputs
    from raycast_phong.renderer.kernels.shadows import shadow_rays
    vertices = np.array([[0.0, 0.0, 0.5], [1.0, 0.0, 0.5], [0.0, 1.0, 0.5]])
    side = -1.0 if from_below else 1.0
    # Tilted away from the side that is seen: the surface is convex toward the viewer and the light.
    outward = (vertices - vertices.mean(axis=0)) * side
    normals = outward / np.linalg.norm(outward, axis=1, keepdims=True) * math.tan(math.radians(30)) + [0, 0, 1]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    inputs = ShadowInputs(vertices=vertices, faces=np.array([[0, 1, 2]], np.int32),
                          face_normals=np.array([[0.0, 0.0, 1.0]]), corner_normals=normals[None],
                          smooth=np.array([True]), light_kind=np.array([1], np.int64),
                          light_vec=np.array([[0.0, 0.0, side]]), two_sided=True)
    b = np.asarray(weights)
    origins, toward, t_max = np.empty((1, 3), np.float32), np.empty((1, 3), np.float32), np.empty(1, np.float32)
    shadow_rays(inputs, np.zeros(1, np.int64), np.array([0], np.int32), np.array([b[1]], np.float32),
                np.array([b[2]], np.float32), np.array([[0.0, 0.0, -side]], np.float32), origins, toward, t_max)
    b = np.array([1 - float(np.float32(b[1])) - float(np.float32(b[2])), np.float32(b[1]), np.float32(b[2])])
    p = b @ vertices
    tangent = [(p - v) - min(0.0, (p - v) @ (side * n)) * (side * n) for v, n in zip(vertices, normals)]
    expected = sum(bj * (v + t) for bj, v, t in zip(b, vertices, tangent))
    assert side * (expected[2] - p[2]) > 0.05  # the smooth surface bulges well out of the facet
    np.testing.assert_allclose(origins[0, :2], expected[:2], rtol=0, atol=1.2e-7)
    offset = side * 8 * max(np.abs(vertices).max(), np.abs(expected).max()) * 2.0 ** -24
    np.testing.assert_allclose(origins[0, 2] - expected[2], offset, rtol=0, atol=1.2e-7)
    np.testing.assert_allclose(toward[0], [0, 0, side])
