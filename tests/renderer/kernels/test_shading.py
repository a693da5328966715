"""Shading models against an exact sphere, and invariants that must hold exactly."""

import math

import numpy as np
import pytest
from conftest import pixel_centre_rays

import raycast_phong as rp
import raycast_phong.scene.schema
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer.kernels import shading
from raycast_phong.renderer.pack import camera_rig

LIGHT = {"type": "point", "position": [2, 2, 3], "diffuse": [0.8, 0.8, 0.8], "specular": [1, 1, 1]}
MATERIAL = {"ka": 1.0, "kd": [0.7, 0.5, 0.3], "ks": 0.5, "shininess": 16}


def sphere_scene(subdivisions: int, shading: str = "phong", size: int = 96, **render):
    return rp.validate_scene({
        "render": {"width": size, "height": size, "shading": shading, "precision": "float64", **render},
        "camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov": 40},
        "ambient": 0.1,
        "lights": [LIGHT],
        "materials": {"m": MATERIAL},
        "objects": [{"shape": "icosphere", "subdivisions": subdivisions, "radius": 1.0, "material": "m"}],
    })


def exact_sphere_image(scene) -> tuple[np.ndarray, np.ndarray]:
    """The model on the true unit sphere, per pixel centre, in numpy float64: image and n·v."""
    rig = camera_rig(scene)
    w, h = scene.render.width, scene.render.height
    _, d = pixel_centre_rays(rig, w, h)
    o = rig.eye
    # |o + t d|² = 1: t² + 2 (o·d) t + |o|² − 1 = 0, nearest root.
    b = d @ o
    disc = b * b - (o @ o - 1)
    hit = disc > 0
    t = -b - np.sqrt(np.where(hit, disc, 0))
    p = o + t[..., None] * d
    n = p  # unit sphere at the origin
    to_light = np.asarray(LIGHT["position"]) - p
    to_light /= np.linalg.norm(to_light, axis=-1, keepdims=True)
    to_viewer = -d
    n_dot_l = np.einsum("...i,...i", n, to_light)
    r = 2 * n_dot_l[..., None] * n - to_light
    v_dot_r = np.einsum("...i,...i", r, to_viewer)
    s = np.where(n_dot_l > 0, np.maximum(v_dot_r, 0) ** MATERIAL["shininess"], 0)
    kd = np.asarray(MATERIAL["kd"])
    image = (0.1 * MATERIAL["ka"] + 0.8 * kd * np.maximum(n_dot_l, 0)[..., None]
             + 1.0 * MATERIAL["ks"] * s[..., None])
    image = np.where(hit[..., None], image, 0.0)
    return image, np.where(hit, np.einsum("...i,...i", n, to_viewer), 0.0)


def test_phong_on_a_fine_icosphere_matches_the_exact_sphere():
    scene = sphere_scene(5)
    image = rp.render(scene).image
    exact, n_dot_v = exact_sphere_image(scene)
    interior = n_dot_v > 0.3  # away from the silhouette, where a pixel may see the mesh or not
    assert interior.sum() > 2000
    error = np.abs(image - exact).max(axis=2)[interior]
    assert error.max() < 0.01, f"max error {error.max():.4f} on interior pixels"


def test_the_sphere_comparison_can_fail():
    """Flat shading on a coarse sphere is far from the exact image: the oracle discriminates."""
    scene = sphere_scene(1, shading="flat")
    exact, n_dot_v = exact_sphere_image(scene)
    error = np.abs(rp.render(scene).image - exact).max(axis=2)[n_dot_v > 0.3]
    assert error.max() > 0.05


def box_scene(shading: str):
    return rp.validate_scene({
        "render": {"width": 64, "height": 48, "shading": shading, "viewer": "infinite", "precision": "float64"},
        "camera": {"type": "orthographic", "position": [3, 2.5, 4], "look_at": [0, 0, 0], "view_height": 3.5},
        "lights": [{"type": "directional", "direction": [-1, -2, -1.5]}],
        "materials": {"m": MATERIAL},
        "objects": [{"shape": "box", "size": [1.5, 1, 1.2], "rotate": [10, 20, 0], "crease_angle": 30,
                     "material": "m"}],
    })


def test_box_flat_gouraud_and_phong_are_identical():
    """Directional light, orthographic camera, infinite viewer, creased box: the model is constant on
    each face, so where it is evaluated cannot matter."""
    flat, gouraud, phong = (rp.render(box_scene(model)).image for model in ("flat", "gouraud", "phong"))
    assert flat.max() > 0.3 and len(np.unique(flat.round(4))) >= 4  # three lit faces and background
    np.testing.assert_allclose(gouraud, flat, atol=1e-6)
    np.testing.assert_allclose(phong, flat, atol=1e-6)


def test_box_without_creases_differs_under_smooth_shading():
    """The same box with crease_angle 180 averages normals across edges: Phong no longer equals flat."""
    scene = box_scene("phong")
    smooth = scene.model_copy(update={"objects": (scene.objects[0].model_copy(update={"crease_angle": 180.0}),)})
    assert np.abs(rp.render(smooth).image - rp.render(box_scene("flat")).image).max() > 0.05


@pytest.mark.parametrize("shading", ["flat", "gouraud", "phong"])
def test_one_and_two_threads_give_bit_identical_images(shading):
    scene = sphere_scene(2, shading=shading, size=200, samples=2)
    one, two = rp.render(scene, threads=1).image, rp.render(scene, threads=2).image
    assert np.array_equal(one, two)


def plane_view(height: float, two_sided: bool):
    return rp.validate_scene({
        "render": {"width": 32, "height": 32, "two_sided": two_sided, "shading": "phong", "precision": "float64"},
        "camera": {"position": [0.3, height, 0.2], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov": 60},
        "lights": [{"type": "point", "position": [0.3, height, 0.2]}],
        "materials": {"m": MATERIAL},
        "objects": [{"shape": "plane", "size": [3, 3], "segments": [3, 3], "material": "m"}],
    })


def test_plane_seen_from_below_with_two_sided_shading_looks_as_from_above():
    above = rp.render(plane_view(2.0, True)).image
    below = rp.render(plane_view(-2.0, True)).image
    assert above.mean() > 0.2
    # Mirrored through the plane, camera and light see the same picture up to the image's flip in x
    # (the camera's right vector turns over with it).
    np.testing.assert_allclose(below[:, ::-1], above, atol=1e-6)


def test_a_plane_is_two_sided_unless_the_scene_says_otherwise():
    """docs/scene-format.md: render.two_sided defaults to true: a scene that does not set it sees a plane from
    below as from above. Catches the default turned to one-sided (only the published schema's text changed)."""
    scene = plane_view(-2.0, True)
    data = scene.data()
    del data["render"]["two_sided"]
    unset = rp.validate_scene(data)
    assert "two_sided" not in unset.render.model_fields_set
    np.testing.assert_array_equal(rp.render(unset).image, rp.render(scene).image)


def test_plane_seen_from_below_one_sided_gets_no_direct_light():
    below = rp.render(plane_view(-2.0, False)).image
    ambient_only = 0.1 * MATERIAL["ka"]
    np.testing.assert_allclose(below, ambient_only, atol=1e-6)


def test_samples_average_sub_pixel_rays():
    """samples = 2 equals the mean of the 2×2 blocks of a render at twice the resolution."""
    coarse = rp.render(sphere_scene(2, size=40, samples=2)).image
    fine = rp.render(sphere_scene(2, size=80)).image
    np.testing.assert_allclose(coarse, fine.reshape(40, 2, 40, 2, 3).mean(axis=(1, 3)), atol=1e-6)


@pytest.mark.parametrize("background", [[0.2, 0.4, 0.6], [0.3, 0, 0], [0, 0, 0.3]])
def test_background_fills_the_misses_and_mixes_with_the_coverage(background):
    """A coloured background (also one with a single non-zero channel): a pixel no sample hits is the colour
    exactly; with 2×2 samples a silhouette pixel is the mean of its samples, background ones included (the
    2×2 blocks of a 2× render)."""
    coarse = rp.render(sphere_scene(2, size=40, samples=2, background=background)).image
    fine = rp.render(sphere_scene(2, size=80, background=background)).image
    np.testing.assert_allclose(coarse[0, 0], background, rtol=0, atol=1e-12)
    np.testing.assert_allclose(coarse, fine.reshape(40, 2, 40, 2, 3).mean(axis=(1, 3)), atol=1e-6)
    mixed = (fine.reshape(40, 2, 40, 2, 3) == background).all(axis=-1).sum(axis=(1, 3))
    assert ((mixed > 0) & (mixed < 4)).sum() > 20  # silhouette pixels where the background is averaged in


def test_term_layers_add_up_to_the_image_and_geometry_layers_are_sane():
    scene = sphere_scene(3, size=48)
    scene = scene.model_copy(update={"output": rp.scene.schema.Output(path="x.exr", aovs=(
        "depth", "normal", "face", "ambient", "diffuse", "specular", "emission"))})
    result = rp.render(scene)
    total = sum(result.aovs[name] for name in ("ambient", "diffuse", "specular", "emission"))
    np.testing.assert_allclose(total, result.image, atol=1e-6)
    hit = result.aovs["face"][..., 0] >= 0
    # The nearest point of the unit sphere is 3 away from the eye at distance 4.
    assert 2.99 < result.aovs["depth"][..., 0][hit].min() < 3.01
    np.testing.assert_allclose(np.linalg.norm(result.aovs["normal"][hit], axis=-1), 1.0, atol=1e-5)
    assert np.isinf(result.aovs["depth"][..., 0][~hit]).all()


# Camera and light off the plane's mirror plane x = 0, so corners left and right differ in colour and the
# camera's right vector has a z part: every coordinate of the projection counts. The second view looks
# along −x, where the right vector has no x part at all.
VIEWS = {"along -z": ([0.5, 0.6, 3.0], [-0.3, 0, -2.0], [0.8, 0.3, 1.5]),
         "along -x": ([4.0, 0.6, -2.0], [-2.0, 0, -2.0], [1.5, 0.3, -1.2])}


@pytest.mark.parametrize("view", sorted(VIEWS))
def test_screen_space_and_perspective_weights_give_the_hand_computed_gouraud_mix(view):
    """Gouraud on one big triangle pair seen at a grazing angle, matte, lit by a point light: the corners'
    colours are k_d max(n·l_j, 0), and each pixel mixes them with weights worked out by hand from its
    ray's hit point: the true barycentrics (perspective-correct), or those of its projection in the
    image plane (x/z, y/z in the camera frame) within the projected triangle (interpolation = "screen").
    Both renders match their own hand mix, and the two differ by as much as the hand mixes do."""
    kd = np.array([0.7, 0.5, 0.3])
    eye, look_at, light = (np.array(v) for v in VIEWS[view])
    size, fov = 48, 60
    base = {
        "render": {"width": size, "height": size, "shading": "gouraud", "precision": "float64"},
        "camera": {"position": eye.tolist(), "look_at": look_at.tolist(), "fov": fov},
        "ambient": 0,
        "lights": [{"type": "point", "position": light.tolist(), "diffuse": 1, "specular": 0}],
        "materials": {"m": {"ka": 0, "kd": kd.tolist(), "ks": 0}},
        "objects": [{"shape": "plane", "size": [4, 8], "translate": [0, 0, -2], "material": "m"}],
    }
    perspective = rp.render(rp.validate_scene(base)).image
    screen = rp.render(rp.validate_scene({**base, "render": {**base["render"], "interpolation": "screen"}})).image

    geometry = build_geometry(rp.validate_scene(base))
    vertices, faces = geometry.vertices, geometry.faces
    to_light = light - vertices
    corner = kd * np.maximum(to_light[:, 1] / np.linalg.norm(to_light, axis=1), 0)[:, None]  # n = +y
    # The camera frame by hand: forward toward look_at, right = forward × up(+y), up = right × forward.
    forward = (look_at - eye) / np.linalg.norm(look_at - eye)
    right = np.cross(forward, [0, 1, 0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    half = math.tan(math.radians(fov) / 2)

    def project(q):
        c = q - eye
        return np.array([c @ right, c @ up]) / (c @ forward)

    def weights(point, a, b, c):
        """Barycentrics of `point` in triangle (a, b, c), 2-D or 3-D (least squares in the plane)."""
        m = np.stack([b - a, c - a], axis=1)
        w1, w2 = np.linalg.lstsq(m, point - a, rcond=None)[0]
        return np.array([1 - w1 - w2, w1, w2])

    expected = {"perspective": np.zeros_like(perspective), "screen": np.zeros_like(screen)}
    hit = np.zeros((size, size), bool)
    for row in range(size):
        for col in range(size):
            x, y = 2 * (col + 0.5) / size - 1, 1 - 2 * (row + 0.5) / size
            d = forward + x * half * right + y * half * up
            if d[1] >= 0:
                continue
            p = eye - eye[1] / d[1] * d  # on the plane y = 0
            for face in faces:
                b = weights(p, *vertices[face])
                if b.min() >= -1e-9:
                    w = weights(project(p), *(project(v) for v in vertices[face]))
                    expected["perspective"][row, col] = b @ corner[face]
                    expected["screen"][row, col] = w @ corner[face]
                    hit[row, col] = True
                    break
    assert hit.sum() > 300
    # Embree's float32 barycentrics carry ~1e-7 relative rounding in the unit frame; a corner colour is ≤ 0.7.
    np.testing.assert_allclose(perspective[hit], expected["perspective"][hit], atol=1e-5)
    np.testing.assert_allclose(screen[hit], expected["screen"][hit], atol=1e-5)
    gap = np.abs(expected["screen"] - expected["perspective"]).max()
    assert gap > 0.005  # 0.036 and 0.0076 in the two views: ≥ 750× the agreement asserted above


def test_vertex_normals_that_cancel_fall_back_to_the_face_normal(tmp_path):
    """File normals point outward in the triangle's plane and sum to zero at its centroid, where the
    centre pixel's ray hits: Phong shading there must use the face normal (+z), not a random one."""
    s = np.sqrt(3) / 2
    (tmp_path / "tri.obj").write_text(f"v 1 0 0\nv -0.5 {s} 0\nv -0.5 {-s} 0\n"
                                      f"vn 1 0 0\nvn -0.5 {s} 0\nvn -0.5 {-s} 0\nf 1//1 2//2 3//3\n")
    scene = rp.validate_scene({
        "render": {"width": 3, "height": 3, "viewer": "infinite", "precision": "float64"},
        "camera": {"type": "orthographic", "position": [0, 0, 3], "view_height": 0.3},
        "ambient": 0,
        "lights": [{"type": "directional", "direction": [0, 0, -1], "diffuse": 1, "specular": 1}],
        "materials": {"m": {"ka": 0, "kd": 0.6, "ks": 0.3, "shininess": 10}},
        "objects": [{"shape": "mesh", "path": "tri.obj", "normals": "file", "material": "m"}],
    }, folder=tmp_path)
    image = rp.render(scene).image
    assert np.isfinite(image).all()
    np.testing.assert_allclose(image[1, 1], 0.6 + 0.3, atol=1e-6)


# The camera frame as the kernel reads it: right, up, forward, orthographic flag; eye at the origin.
LOOKING_DOWN_MINUS_Z = np.array([1, 0, 0, 0, 1, 0, 0, 0, -1, 0], np.float64)


def test_screen_weights_in_a_triangle_in_front_of_the_eye_are_the_projected_ones():
    """All corners in front: the weights are the hit's 2-D barycentrics in the projected triangle."""
    vertices = np.array([[0, 0, -1], [2, 0, -3], [0, 1, -2]], np.float64)
    true = np.array([0.2, 0.5, 0.3])
    got = shading._screen_weights(*true, vertices, 0, 1, 2, np.zeros(3), LOOKING_DOWN_MINUS_Z, 1.0)
    projected = vertices[:, :2] / -vertices[:, 2:]          # (x/z, y/z) with z the depth along forward
    hit = true @ vertices
    screen = hit[:2] / -hit[2]
    # Solve screen = Σ w_i projected_i with Σ w_i = 1 independently of the kernel.
    expected = np.linalg.solve(np.vstack([projected.T, np.ones(3)]), np.append(screen, 1.0))
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    assert np.abs(np.asarray(got) - true).max() > 0.05  # a receding triangle: screen ≠ perspective weights


@pytest.mark.parametrize("behind", [1.0, 0.0, 1e-9])
def test_a_triangle_reaching_behind_the_eye_keeps_its_true_weights(behind):
    """A corner at or behind the eye plane has no image; projecting it anyway gave weights outside [0, 1]."""
    vertices = np.array([[0, 0, -1], [1, 0, -1], [0, 0.5, behind]], np.float64)
    true = (0.3, 0.3, 0.4)  # the hit (0.3, 0.2, 0.4 behind − 0.6) is in front of the eye
    got = shading._screen_weights(*true, vertices, 0, 1, 2, np.zeros(3), LOOKING_DOWN_MINUS_Z, 1.0)
    np.testing.assert_allclose(got, true, rtol=0, atol=1e-15)


def test_screen_interpolation_stays_inside_the_vertex_values_on_a_floor_reaching_behind_the_eye():
    """Gouraud, screen weights, a 40 × 40 floor whose far corners are behind the camera: every pixel is a
    convex mix of its corners' intensities, kd I_d (n·l) with n·l = 3/|light − corner| (no ambient, no
    specular), so it lies between the smallest and the largest of the four."""
    light = np.array([0.0, 3.0, -3.0])
    corners = np.array([[x, 0.0, z] for x in (-20, 20) for z in (-20, 20)])
    n_dot_l = 3.0 / np.linalg.norm(light - corners, axis=1)
    scene = rp.validate_scene({
        "render": {"width": 48, "height": 32, "shading": "gouraud", "interpolation": "screen",
                   "precision": "float64"},
        "camera": {"position": [0, 1, 0], "look_at": [0, 0, -5], "fov": 90},
        "ambient": 0,
        "lights": [{"type": "point", "position": light.tolist(), "diffuse": 1.0}],
        "materials": {"m": {"ka": 0, "kd": 1.0, "ks": 0}},
        "objects": [{"shape": "plane", "size": [40, 40], "material": "m"}],
    })
    image = rp.render(scene).image[..., 0]
    floor = image[image > 0]
    assert floor.size > 0.4 * image.size
    assert n_dot_l.min() - 1e-12 <= floor.min() and floor.max() <= n_dot_l.max() + 1e-12


def test_the_geometry_writes_the_columns_and_codes_the_kernels_read():
    """The material row order and the shading model codes have one home, codes.py, which the geometry stage
    writes with and the kernels' layout reads: each coefficient lands in the column layout names for it."""
    from raycast_phong.codes import MODEL_CODE
    from raycast_phong.geometry.materials import material_rows
    from raycast_phong.renderer.kernels import layout
    rows = material_rows(*(np.full((2, 3), value) for value in (1.0, 2.0, 3.0, 4.0)), np.full(2, 5.0))
    assert rows.shape == (2, layout.MATERIAL_COLUMNS)
    for column, value in ((layout.KA, 1), (layout.KD, 2), (layout.KS, 3), (layout.KE, 4)):
        assert (rows[:, column:column + 3] == value).all()
    assert (rows[:, layout.SHININESS] == 5).all()
    assert {model.value: code for model, code in MODEL_CODE.items()} == {
        "flat": layout.FLAT, "gouraud": layout.GOURAUD, "phong": layout.PHONG}


@pytest.mark.parametrize("shading", ["flat", "phong"])
def test_term_counts_are_the_hits_that_evaluated_each_term(shading):
    """The kernel counts a run of hits with one mask of evaluated terms at once (the mask changes across the
    terminator, row after row): the counts must still be the hits, one by one. One sample a pixel: a hit
    evaluated the diffuse term exactly where its diffuse layer is positive (n·l > 0, k_d, I_d > 0), the
    highlight there too, and the scene's ambient everywhere."""
    scene = sphere_scene(3, shading=shading, size=48)
    scene = scene.model_copy(update={"output": rp.scene.schema.Output(path="x.exr", aovs=("face", "diffuse"))})
    result = rp.render(scene)
    hit = result.aovs["face"][..., 0] >= 0
    lit = hit & (result.aovs["diffuse"].max(axis=-1) > 0)
    assert 0 < lit.sum() < hit.sum()  # the terminator is in view: the mask changes within rows
    assert result.counts["diffuse"] == result.counts["specular"] == lit.sum()
    assert result.counts["scene_ambient"] == hit.sum()


# Lights that each change what the engine does per point and light (position, direction, f_att, light ambient,
# highlight): every model is compared with the numpy oracle under each, and under all of them at once.
ORACLE_LIGHTS = {
    "point": {"type": "point", "position": [2, 2, 3], "diffuse": [0.8, 0.7, 0.6], "specular": [1, 1, 1]},
    "directional": {"type": "directional", "direction": [-2, -1, -3], "diffuse": [0.6, 0.7, 0.8],
                    "specular": [0.9, 0.9, 0.9]},
    "point 1/d², light ambient": {"type": "point", "position": [-2, 1, 2.5], "attenuation": "inverse_square",
                                  "ambient": [0.3, 0.2, 0.1], "diffuse": [9, 8, 7], "specular": [12, 12, 12]},
    "point c + l d + q d²": {"type": "point", "position": [0.5, -2, 2], "attenuation": [0.5, 0.2, 0.1],
                             "ambient": [0.1, 0.2, 0.3], "diffuse": [0.9, 0.9, 0.9], "specular": [0.5, 0.5, 0.5]},
}


def oracle_image(scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The engine's model per pixel centre, in float64 numpy and independent of the kernels: each pixel's ray
    meets the face the render's face layer names (Möller–Trumbore here), and reference.illuminate_exact is
    evaluated where the face's model says (flat: the centroid with the face normal; Gouraud: the corners, mixed
    with the hit's weights; Phong: the hit with the mixed normal renormalised). Returns the render's image, the
    oracle's and where the rays hit."""
    from raycast_phong.tools.reference import illuminate_exact, material_table
    result = rp.render(scene)
    hit_face = result.aovs["face"][..., 0].astype(np.int64)
    hit = hit_face >= 0
    geometry = build_geometry(scene)
    eye, d = pixel_centre_rays(camera_rig(scene), scene.render.width, scene.render.height)
    f, d = hit_face[hit], d[hit]
    corners = geometry.vertices[geometry.faces[f]]  # (H, 3 corners, 3)
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    p_vec = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p_vec)
    t_vec = eye - corners[:, 0]
    b1 = np.einsum("ij,ij->i", t_vec, p_vec) / det
    b2 = np.einsum("ij,ij->i", d, np.cross(t_vec, e1)) / det
    weights = np.stack([1 - b1 - b2, b1, b2], axis=1)  # (H, 3)
    rows = np.broadcast_to(material_table(scene)[0], (len(f), 13))
    visible = np.ones((len(f), len(scene.lights)), bool)

    def model(points, normals):
        to_viewer = eye - points
        to_viewer /= np.linalg.norm(to_viewer, axis=1, keepdims=True)
        return sum(illuminate_exact(scene, points, normals, to_viewer, rows, visible, 1.0))

    kind = scene.render.shading.value
    if kind == "flat":
        colour = model(corners.mean(axis=1), geometry.face_normals[f])
    elif kind == "phong":
        mixed = np.einsum("hc,hci->hi", weights, geometry.corner_normals[f])
        colour = model(np.einsum("hc,hci->hi", weights, corners), mixed / np.linalg.norm(mixed, axis=1)[:, None])
    else:
        colour = sum(weights[:, c, None] * model(corners[:, c], geometry.corner_normals[f][:, c]) for c in range(3))
    oracle = np.zeros_like(result.image, dtype=np.float64)
    oracle[hit] = colour
    return result.image, oracle, hit


@pytest.mark.parametrize("shading", ["flat", "gouraud", "phong"])
@pytest.mark.parametrize("lights", [*ORACLE_LIGHTS, "all four"])
@pytest.mark.parametrize("specular", ["phong", "blinn"])
def test_the_engine_evaluates_the_model_as_the_numpy_oracle(shading, lights, specular):
    """Every model, each kind of light alone and all four together (the engine's per-light lanes in the lights'
    order), a material with emission: the image is the oracle's, evaluated where the model says, to 1e-6 of its
    float64 rounding and Embree's float32 hit weights. The oracle is read in the pixel's own terms, so a term
    left out, a light skipped or taken twice, a corner weighted with another's weight or a normal not
    renormalised each move pixels by far more (checked by breaking the engine on purpose)."""
    chosen = list(ORACLE_LIGHTS.values()) if lights == "all four" else [ORACLE_LIGHTS[lights]]
    scene = rp.validate_scene({
        "render": {"width": 40, "height": 40, "shading": shading, "specular": specular, "precision": "float64"},
        "camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov": 40},
        "ambient": [0.1, 0.05, 0.02],
        "lights": chosen,
        "materials": {"m": {**MATERIAL, "ke": [0.02, 0.03, 0.01]}},
        "objects": [{"shape": "icosphere", "subdivisions": 2, "radius": 1.0, "material": "m"}],
        "output": {"path": "x.exr", "aovs": ["face"]},
    })
    image, oracle, hit = oracle_image(scene)
    assert hit.sum() > 400 and image.max() > 0.3
    np.testing.assert_allclose(image, oracle, rtol=0, atol=1e-6)
