"""The analytic reference against values worked out by hand at chosen pixels (to 1e-9)."""

import math
from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.tools.accuracy import fine_reference, mesh_coverage
from raycast_phong.tools.reference import analytic_reference

SCENES = Path(__file__).resolve().parents[2] / "scenes"

HAND = 1e-9  # every expected value below is a closed form; float64 rounding is ~1e-15


def scene(objects, lights, camera=None, size=(5, 5), material=None, **render):
    return rp.validate_scene({
        "render": {"width": size[0], "height": size[1], "precision": "float64", **render},
        "camera": camera or {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov": 40},
        "ambient": 0.1,
        "lights": lights,
        "materials": {"m": material or {"ka": 1.0, "kd": [0.7, 0.5, 0.3], "ks": 0.5, "shininess": 16}},
        "objects": [{"material": "m", **obj} for obj in objects],
    })


# Orthographic, looking down −z with a 4 × 4 view over 4 × 4 pixels: pixel (col, row) has its centre at
# world x = col − 1.5, y = 1.5 − row, and every ray travels along (0, 0, −1); v = (0, 0, 1).
ORTHO = {"type": "orthographic", "position": [0, 0, 10], "look_at": [0, 0, 0], "view_height": 4}
OVERHEAD = {"type": "directional", "direction": [0, 0, -1], "diffuse": 0.8, "specular": 1.0}  # l = (0, 0, 1)
KD, KS, F = np.array([0.7, 0.5, 0.3]), 0.5, 16


def lit_from_above(normal, ka=1.0):
    """The model for OVERHEAD and an orthographic viewer at a unit normal n: l = v = (0, 0, 1)."""
    n_dot_l = normal[2]
    r_dot_v = 2 * n_dot_l * normal[2] - 1  # r = 2(n·l)n − l
    return 0.1 * ka + 0.8 * KD * max(n_dot_l, 0) + KS * (max(r_dot_v, 0) ** F if n_dot_l > 0 else 0)


def test_sphere_centre_pixel_perspective_local_viewer():
    # The centre ray of a 5 × 5 image hits the unit sphere at (0, 0, 1): n = v = (0, 0, 1), l = (1, 1, 1)/√3.
    light = {"type": "point", "position": [2, 2, 3], "diffuse": 0.8, "specular": 1.0}
    ref = analytic_reference(scene([{"shape": "icosphere"}], [light]))
    s = 1 / math.sqrt(3)
    expected = 0.1 + 0.8 * KD * s + KS * s ** F  # r·v = 2(n·l)n_z − l_z = 1/√3
    np.testing.assert_allclose(ref.image[2, 2], expected, rtol=0, atol=HAND)
    assert ref.coverage[2, 2] == 1 and ref.coverage[0, 0] == 0


@pytest.mark.parametrize(("rotate", "point"), [([0, 0, 0], (1.5, 0.5)), ([0, 0, 90], (0.5, 1.5))])
def test_rotated_ellipsoid_normal_is_the_inverse_transpose(rotate, point):
    # scale [2, 1, 1], then Rz 90°: the long axis turns from x to y (world = T Rz Ry Rx S local).
    obj = {"shape": "uv_sphere", "scale": [2, 1, 1], "rotate": rotate}
    ref = analytic_reference(scene([obj], [OVERHEAD], ORTHO, size=(4, 4)))
    x, y = point
    a2, b2 = (4.0, 1.0) if rotate[2] == 0 else (1.0, 4.0)
    z = math.sqrt(1 - x * x / a2 - y * y / b2)  # 0.1875 = 1 − 0.5625 − 0.25
    gradient = np.array([x / a2, y / b2, z])
    col, row = int(x + 1.5), int(1.5 - y)
    np.testing.assert_allclose(ref.image[row, col], lit_from_above(gradient / np.linalg.norm(gradient)),
                               rtol=0, atol=HAND)


def test_box_plane_cylinder_at_hand_picked_pixels():
    # Three objects seen from above, each under its own pixel column.
    objects = [
        {"shape": "box", "size": [0.8, 4, 0.5], "translate": [-1.5, 0, 0]},                  # top face z = 0.25
        {"shape": "plane", "size": [0.8, 4], "rotate": [90, 0, 0], "translate": [-0.5, 0, 0]},  # Rx 90°: +y → +z
        {"shape": "cylinder", "radius": 0.4, "height": 4, "rotate": [90, 0, 0], "translate": [0.5, 0, 0]},
    ]
    ref = analytic_reference(scene(objects, [OVERHEAD], ORTHO, size=(4, 4)))
    up = np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(ref.image[0, 0], lit_from_above(up), atol=HAND)  # box top
    np.testing.assert_allclose(ref.image[0, 1], lit_from_above(up), atol=HAND)  # plane
    # The cylinder lies along world y after Rx 90°, its axis under column x = 0.5: n = (0, 0, 1) there.
    np.testing.assert_allclose(ref.image[1, 2], lit_from_above(up), atol=HAND)
    assert ref.coverage[:, 3].sum() == 0  # nothing under x = 1.5


def test_cylinder_side_and_cap():
    # Cylinder r = 1, height 1 along z, seen from above: pixel (1, 1) → (−0.5, 0.5) hits the top cap,
    # n = (0, 0, 1). Tilted by Ry 90° (axis along x), pixel (1, 1) hits the side at y = 0.5, z = √0.75.
    upright = analytic_reference(scene([{"shape": "cylinder", "radius": 1, "height": 1}], [OVERHEAD], ORTHO,
                                       size=(4, 4)))
    np.testing.assert_allclose(upright.image[1, 1], lit_from_above(np.array([0.0, 0, 1])), atol=HAND)
    lying = analytic_reference(scene([{"shape": "cylinder", "radius": 1, "height": 4, "rotate": [0, 90, 0]}],
                                     [OVERHEAD], ORTHO, size=(4, 4)))
    np.testing.assert_allclose(lying.image[1, 1], lit_from_above(np.array([0.0, 0.5, math.sqrt(0.75)])), atol=HAND)


def test_torus_tube_top_and_slope():
    # Torus R = 1, r = 0.5 at the origin, seen from above; pixel (col, row) looks at (col − 1.5, 1.5 − row).
    # Pixel (2, 2) → (0.5, −0.5): ρ = √0.5 from the axis, tube offset ρ − R, z = √(r² − (ρ − R)²).
    obj = {"shape": "torus", "major_radius": 1.0, "minor_radius": 0.5}
    ref = analytic_reference(scene([obj], [OVERHEAD], ORTHO, size=(4, 4)))
    rho = math.sqrt(0.5)
    z = math.sqrt(0.25 - (rho - 1) ** 2)
    normal = np.array([0.5 * (1 - 1 / rho), -0.5 * (1 - 1 / rho), z]) / 0.5  # (p − R p_xy/ρ) / r
    np.testing.assert_allclose(np.linalg.norm(normal), 1, atol=1e-12)
    np.testing.assert_allclose(ref.image[2, 2], lit_from_above(normal), atol=HAND)
    # Pixel (0, 3) → (−1.5, −1.5): ρ = 2.12 > R + r, a miss.
    assert ref.coverage[3, 0] == 0


@pytest.mark.parametrize("attenuation", ["inverse_square", [1.0, 0.5, 0.25]])
def test_attenuation_and_light_ambient(attenuation):
    # Light 2 above the top of the unit sphere, seen from the side by an orthographic camera along −x?
    # Simpler: perspective centre pixel, light on the axis at (0, 0, 3): d = 2, l = n = v = (0, 0, 1).
    light = {"type": "point", "position": [0, 0, 3], "diffuse": 0.8, "specular": 1.0, "ambient": 0.3,
             "attenuation": attenuation}
    ref = analytic_reference(scene([{"shape": "icosphere"}], [light]))
    weight = 0.25 if attenuation == "inverse_square" else min(1.0, 1 / (1 + 0.5 * 2 + 0.25 * 4))
    expected = 0.1 + weight * (0.3 + 0.8 * KD + KS)  # r = v exactly: S = 1
    np.testing.assert_allclose(ref.image[2, 2], expected, atol=HAND)


def test_blinn_and_infinite_viewer():
    # Infinite viewer: v = −forward = (0, 0, 1) even off-axis; centre pixel n = (0, 0, 1), l = (1, 1, 1)/√3,
    # h = normalize(l + v), n·h = (1/√3 + 1) / |l + v|.
    light = {"type": "point", "position": [2, 2, 3], "diffuse": 0.8, "specular": 1.0}
    ref = analytic_reference(scene([{"shape": "icosphere"}], [light], specular="blinn", viewer="infinite"))
    s = 1 / math.sqrt(3)
    n_dot_h = (s + 1) / math.sqrt(2 * s * s + (s + 1) ** 2)
    np.testing.assert_allclose(ref.image[2, 2], 0.1 + 0.8 * KD * s + KS * n_dot_h ** F, atol=HAND)


@pytest.mark.parametrize("two_sided", [True, False])
def test_plane_seen_from_below(two_sided):
    # Camera below a plane (normal +y) looking up; light below too. Two-sided: n flips to (0, −1, 0), lit head-on.
    camera = {"position": [0, -4, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov": 40}
    light = {"type": "point", "position": [0, -3, 0], "diffuse": 0.8, "specular": 1.0}
    ref = analytic_reference(scene([{"shape": "plane", "size": [4, 4]}], [light], camera, two_sided=two_sided))
    expected = 0.1 + (0.8 * KD + KS if two_sided else 0)  # one-sided: n·l = −1 ≤ 0, ambient only
    np.testing.assert_allclose(ref.image[2, 2], expected, atol=HAND)


def test_global_mode_shadow_from_an_exact_sphere():
    # A small sphere between a plane and an overhead light: the pixel under it gets ambient only.
    # The centre ray runs from (0, 4, 4) to the origin, 1/√2 from the sphere's centre: it sees the plane.
    camera = {"position": [0, 4, 4], "look_at": [0, 0, 0], "fov": 40}
    light = {"type": "point", "position": [0, 3, 0], "diffuse": 0.8, "specular": 1.0}
    objects = [{"shape": "plane", "size": [4, 4]}, {"shape": "icosphere", "radius": 0.05, "translate": [1, 1, 0]}]
    lit = analytic_reference(scene(objects, [light], camera, mode="global"))
    blocked = analytic_reference(scene([objects[0], {**objects[1], "translate": [0, 1, 0]}], [light], camera,
                                       mode="global"))
    assert lit.image[2, 2, 0] > 0.3
    np.testing.assert_allclose(blocked.image[2, 2], 0.1 * np.ones(3), atol=HAND)  # ka I_a alone


def test_samples_average_the_sub_pixel_rays():
    light = {"type": "point", "position": [2, 2, 3], "diffuse": 0.8, "specular": 1.0}
    one = analytic_reference(scene([{"shape": "icosphere"}], [light], size=(10, 10)))
    two = analytic_reference(scene([{"shape": "icosphere"}], [light], size=(5, 5), samples=2))
    np.testing.assert_allclose(two.image, one.image.reshape(5, 2, 5, 2, 3).mean(axis=(1, 3)), atol=1e-14)
    np.testing.assert_allclose(two.coverage, one.coverage.reshape(5, 2, 5, 2).mean(axis=(1, 3)))


def test_a_mesh_object_has_no_closed_form(tmp_path):
    s = rp.validate_scene({"objects": [{"shape": "mesh", "path": "x.ply"}]}, source="scene.toml")
    with pytest.raises(rp.SceneError, match=r'^scene.toml: objects.0.shape: "mesh" has no closed form; use --fine N$'):
        analytic_reference(s)


def test_fine_phong_mesh_converges_to_the_analytic_reference():
    light = {"type": "point", "position": [2, 2, 3], "diffuse": 0.8, "specular": 1.0}
    coarse = scene([{"shape": "icosphere", "subdivisions": 1}], [light], size=(48, 48))
    exact = analytic_reference(coarse)
    errors = []
    for levels in (1, 3):
        fine = fine_reference(coarse, levels)
        both = (fine.coverage == 1) & (exact.coverage == 1)
        errors.append(np.sqrt(((fine.image - exact.image)[both] ** 2).mean()))
    assert errors[1] < errors[0] / 4 and errors[1] < 3e-3
    assert ((mesh_coverage(coarse) > 0) != (exact.coverage > 0)).sum() > 0  # the 80-face silhouette differs


@pytest.mark.parametrize("sideways", [(0.0, 0.0), (3e-7, -5e-7)])
def test_a_light_inside_the_distance_floor_is_head_on_in_the_reference_too(sideways):
    """The oracle keeps the kernel's rule: within 1e-6 × the half-extent (2e-6 for this 4 × 4 plane), l = n.

    At the centre pixel (x = y = 0 exactly in float64), f_att = 1/(2e-6)² and n·l = v·r = 1.
    """
    light = {"type": "point", "position": [*sideways, 1e-12], "attenuation": "inverse_square",
             "diffuse": 0.8, "specular": 1.0}
    plane = {"shape": "plane", "size": [4, 4], "rotate": [90, 0, 0]}
    ref = analytic_reference(scene([plane], [light], ORTHO, size=(5, 5)))
    expected = 0.1 + (0.8 * KD + KS) / (2e-6) ** 2
    np.testing.assert_allclose(ref.image[2, 2], expected, rtol=1e-12)


@pytest.mark.parametrize("colour", ["display", "linear"])
def test_the_analytic_reference_applies_colour_maps_and_a_textured_sphere_converges(tmp_path, colour):
    """scenes/textured_sphere.toml with a smooth ramp k_d map (an 8-bit PNG: its bytes used as stored in display
    colour, decoded from sRGB in linear colour, on both sides) against the analytic reference, which reads the
    map itself, decodes it (or not) itself and looks it up at the exact UVs: the RMSE falls as the sphere is
    refined (the UVs' and the normals' interpolation error), and without the map in the reference, or with the
    other colour setting's decoding, it would be far off."""
    import OpenImageIO as oiio

    from raycast_phong.tools.accuracy import measured
    from raycast_phong.tools.reference import ramp
    n = 64
    y, x = np.mgrid[0:n, 0:n]
    texels = np.round(255 * ramp((x + 0.5) / n, 1 - (y + 0.5) / n)).astype(np.uint8)
    buffer = oiio.ImageBuf(oiio.ImageSpec(n, n, 3, oiio.UINT8))
    buffer.set_pixels(oiio.ROI(0, n, 0, n, 0, 1, 0, 3), np.ascontiguousarray(texels))
    assert buffer.write(str(tmp_path / "ramp.png"))
    errors = []
    for segments in ("[16,32]", "[64,128]"):
        scene = rp.load_scene(SCENES / "textured_sphere.toml", ["render.width=160", "render.height=120",
                                                                f"objects.0.segments={segments}",
                                                                f'materials.checker.kd_map="{tmp_path / "ramp.png"}"',
                                                                f"render.colour={colour}"])
        errors.append(measured(scene, rp.render(scene), "analytic").errors.rmse)
    # Falls with the tessellation; what stays (~1e-3) is mostly the wrap seam, which coarser mip levels blur
    # wider than the reference's level-0 lookup.
    assert errors[1] < 0.75 * errors[0] and errors[1] < 0.002, errors
    plain = rp.load_scene(SCENES / "textured_sphere.toml", ["render.width=160", "render.height=120",
                                                            "objects.0.segments=[64,128]",
                                                            f'materials.checker.kd_map="{tmp_path / "ramp.png"}"',
                                                            f"render.colour={colour}"])
    untextured = plain.model_copy(update={"materials": {"checker": plain.materials["checker"].model_copy(
        update={"kd_map": None})}})
    assert measured(plain, rp.render(untextured), "analytic").errors.rmse > 10 * errors[1]
    # The oracle follows the setting on its own: the other setting's render is far from this one's reference.
    other = plain.model_copy(update={"render": plain.render.model_copy(
        update={"colour": "linear" if colour == "display" else "display"})})
    assert measured(plain, rp.render(other), "analytic").errors.rmse > 10 * errors[1]


def test_a_textured_shape_without_exact_uvs_is_refused_in_one_line(tmp_path):
    from raycast_phong.errors import SceneError
    scene = rp.load_scene(SCENES / "textured_sphere.toml", ["objects.0.shape=\"cylinder\""])
    with pytest.raises(SceneError, match="planes and spheres only"):
        analytic_reference(scene)


def _exact_sphere_t(origin, direction, radius=1.0):
    """The nearer root of |o + t d|² = r² in 60-digit decimal arithmetic (inf on a miss), and the discriminant
    over a r² (how far from grazing): a reference apart from the float64 code it checks."""
    from decimal import Decimal, localcontext
    with localcontext() as context:
        context.prec = 60
        o = [Decimal(float(x)) for x in origin]
        d = [Decimal(float(x)) for x in direction]
        a = sum(x * x for x in d)
        b = sum(x * y for x, y in zip(o, d))
        c = sum(x * x for x in o) - Decimal(radius) ** 2
        disc = b * b - a * c
        return (math.inf if disc < 0 else float((-b - disc.sqrt()) / a)), float(disc / (a * Decimal(radius) ** 2))


@pytest.mark.parametrize("distance", [1e3, 1e7, 1e9])
def test_the_oracle_s_sphere_is_exact_at_any_distance(distance):
    """Rays from `distance` radii away aimed across the limb (issue 47): at 1e7 the old discriminant b² − ac was
    rounding alone and 193 pixels of a render's reference were wrong. Hit or miss and t agree with 60 digits,
    but for rays grazing within float64's rounding of the limb (|disc| < 1e-9 a r²)."""
    from raycast_phong.tools.reference import _sphere
    rng = np.random.default_rng(5)
    eye = np.array([0.3, 0.2, 1.0]) * distance / math.sqrt(1.13)
    targets = rng.uniform(-1.2, 1.2, (400, 3)) * [1, 1, 0]  # across the sphere's disc and past its limb
    directions = targets - eye
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    origins = np.broadcast_to(eye, directions.shape).copy()
    t = _sphere(origins, directions, type("Sphere", (), {"radius": 1.0}), 0.0)
    hits = 0
    for k in range(len(t)):
        exact, disc = _exact_sphere_t(origins[k], directions[k])
        if abs(disc) < 1e-9:
            continue
        hits += math.isfinite(exact)
        assert math.isfinite(t[k]) == math.isfinite(exact), (k, disc)
        if math.isfinite(exact):
            # p = o − (b/a) d is good to about ε|o| a coordinate, so √disc to ε|o|/√disc: t's bound follows.
            eps = np.finfo(np.float64).eps
            assert abs(t[k] - exact) <= 8 * eps * distance / math.sqrt(disc) + 4 * eps * exact, (k, disc)
    assert 100 < hits < 390  # both hits and misses were checked


def test_the_oracle_lights_nothing_from_a_light_in_the_surface_s_plane():
    """As the kernels (tolerances.LIT_ROUNDINGS): n·l of rounding alone is 0, so the reference is flat ambient
    where the old rule (l·n > 0) speckled it with highlights of up to +0.3 (issue 47)."""
    from raycast_phong.tools.stability import light_in_plane_scene
    for precision in ("float32", "float64"):
        scene = light_in_plane_scene(precision)
        reference = analytic_reference(scene)
        covered = reference.coverage > 0.999
        assert covered.sum() > 1000 and np.abs(reference.image[covered] - 0.1).max() < 1e-12
        image = rp.render(scene).image
        assert np.abs(image[covered] - reference.image[covered]).max() < 1e-6


def test_the_oracle_s_wrap_modes_at_and_past_each_edge():
    """Texel indices −2 … 6 of a 3-texel row: "mirror" reflects about each edge, repeating the edge texel
    (… 1 0 | 0 1 2 | 2 1 0 | 0), "clamp" holds the edge texel and "repeat" starts over."""
    from raycast_phong.tools.reference import _wrapped
    indices = np.arange(-2, 7)
    assert _wrapped(indices, 3, "mirror").tolist() == [1, 0, 0, 1, 2, 2, 1, 0, 0]
    assert _wrapped(indices, 3, "clamp").tolist() == [0, 0, 0, 1, 2, 2, 2, 2, 2]
    assert _wrapped(indices, 3, "repeat").tolist() == [1, 2, 0, 1, 2, 0, 1, 2, 0]


def test_an_emission_map_multiplies_k_e_and_leaves_k_s_alone():
    """A k_e map of 0.5 everywhere halves the k_e columns (9–11) of the hit's material row; k_a, k_d, k_s and
    the shininess keep their values (k_s is never mapped)."""
    from raycast_phong.tools.reference import ExactScene, textured_rows
    plane = scene([{"shape": "plane"}], [OVERHEAD])
    rows = np.arange(1.0, 14.0)[None, :]
    maps = {0: {"ke": (np.full((2, 2, 3), 0.5), "repeat")}}
    found = textured_rows(plane, ExactScene(plane), maps, rows, np.array([0]), np.array([[0.1, 0.0, 0.2]]))
    expected = rows.copy()
    expected[0, 9:12] /= 2
    np.testing.assert_allclose(found, expected, atol=HAND)


def test_the_oracle_reads_a_half_float_map_as_linear_and_a_grey_alpha_png_as_grey(tmp_path):
    """A half-float EXR holds linear values: render.colour = "linear" takes 0.5 as 0.5, with no sRGB decode
    (which would give 0.214). A grey + alpha PNG is grey in all three channels, whatever its alpha."""
    import OpenImageIO as oiio
    from PIL import Image

    from raycast_phong.tools.reference import read_map
    half = oiio.ImageBuf(oiio.ImageSpec(2, 2, 3, oiio.HALF))
    oiio.ImageBufAlgo.fill(half, (0.5, 0.5, 0.5))
    assert half.write(str(tmp_path / "half.exr"))
    np.testing.assert_allclose(read_map(tmp_path / "half.exr", "linear"), 0.5, atol=1e-6)
    Image.fromarray(np.full((2, 3, 2), (51, 200), np.uint8), "LA").save(tmp_path / "grey.png")
    np.testing.assert_allclose(read_map(tmp_path / "grey.png", "display"), np.full((2, 3, 3), 0.2), atol=1e-6)
