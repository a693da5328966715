"""The oracle: the illumination model on the true surfaces of the analytic shapes, in float64 numpy.

Written from the scene format alone (docs/scene-format.md), it imports none of the renderer's stages:
its own camera frame and pixel-sample rays, its own object placement (world = T · Rz · Ry · Rx · S ·
local, so a non-uniform scale gives an ellipsoid), its own exact sphere, box, plane, cylinder and torus
intersections (the ray taken into object space by the inverse affine map, the normal back by the
inverse transpose), its own evaluation of the model; global mode casts analytic shadow rays. A bug in
a stage therefore shows as a difference instead of being shared. It shares only the Scene record and
the model's named tolerances. A mesh file has no closed form: accuracy.fine_reference is for those.
Colour maps on planes and spheres are read with its own OpenImageIO call and, as the scene's render.colour
says, its own sRGB decoding ("linear") or none ("display"), and looked up bilinearly at the exact UVs of the
exact hit (no mip level: the texture at the point itself), so the study and `accuracy` can measure a textured
scene in either setting.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scene.schema import Object, Scene, SceneError, SpecularModel, Viewer
from ..tolerances import LIT_ROUNDINGS, MIN_DISTANCE

TILE_SAMPLES = 1 << 16  # rays per tile: the torus's 4×4 eigenproblems stay a few MB
UNLIT = LIT_ROUNDINGS * 2.0 ** -53  # n·l of float64 rounding alone: 0, as the kernels take it in their precision
SHADOW_OFFSET = 1e-9    # × the scene's half-extent: float64 exact hits sit ~1e-15 off the surface


@dataclass(frozen=True)
class CameraFrame:
    """The camera as the scene format defines it: an orthonormal frame and the image plane's half-size."""
    eye: np.ndarray        # (3,) float64
    right: np.ndarray      # (3,) unit: forward × up, normalised
    up: np.ndarray         # (3,) unit: right × forward
    forward: np.ndarray    # (3,) unit, toward look_at
    half_width: float      # at distance 1 (perspective: tan(fov/2) · W/H) or in world units (orthographic)
    half_height: float
    orthographic: bool


def camera_frame(scene: Scene) -> CameraFrame:
    """The scene's camera: forward = normalize(look_at − position), right = normalize(forward × up)."""
    camera, width, height = scene.camera, scene.render.width, scene.render.height
    eye = np.array(camera.position, np.float64)
    forward = np.array(camera.look_at, np.float64) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.array(camera.up, np.float64))
    right /= np.linalg.norm(right)
    orthographic = camera.type == "orthographic"
    half_height = camera.view_height / 2 if orthographic else math.tan(math.radians(camera.fov) / 2)
    return CameraFrame(eye, right, np.cross(right, forward), forward, half_height * width / height, half_height,
                       orthographic)


def rotation(obj: Object) -> np.ndarray:
    """R = Rz · Ry · Rx of the object's `rotate` angles in degrees (x first), a 3×3 matrix."""
    def about(axis: int, degrees: float) -> np.ndarray:
        c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
        i, j = [(1, 2), (2, 0), (0, 1)][axis]  # the plane the rotation turns: y–z, z–x, x–y
        m = np.eye(3)
        m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
        return m
    rx, ry, rz = obj.rotate
    return about(2, rz) @ about(1, ry) @ about(0, rx)


@dataclass(frozen=True, eq=False)
class ReferenceImage:
    """A reference render and what the metrics need besides the colour."""
    image: np.ndarray     # (H, W, 3) float64, linear display values (mean over the pixel's samples)
    specular: np.ndarray  # (H, W, 3) float64, the specular term alone (highlight loss)
    coverage: np.ndarray  # (H, W) float64, share of the pixel's samples that hit a surface
    kind: str             # "analytic", or "fine N" for a self-convergence reference


# ---------------------------------------------------------------- exact intersections in object space

def _discriminant(o, d, a, b, r2):
    """b² − a c of |o + t d|² = r² (a = d·d, b = o·d, c = o·o − r²) without cancellation: a (r² − |p|²), p = o − (b/a) d
    the foot of the perpendicular from the centre (Haines et al., Ray Tracing Gems ch. 7). b² and a c agree
    to all their digits for an eye 1e7 radii away, so their difference is rounding alone."""
    with np.errstate(divide="ignore", invalid="ignore"):
        p = o - (b / a)[:, None] * d
    return a * (r2 - np.einsum("ij,ij->i", p, p))


def _roots(o, d, r):
    """Both roots t of |o + t d|² = r² (rows of any width: a circle's in x–y too), the cancellation-free pair
    q/a, c/q; inf where there is none."""
    a, b, c = np.einsum("ij,ij->i", d, d), np.einsum("ij,ij->i", o, d), np.einsum("ij,ij->i", o, o) - r * r
    disc = _discriminant(o, d, a, b, r * r)
    q = -(b + np.copysign(np.sqrt(np.maximum(disc, 0)), b))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(disc >= 0, q / a, np.inf), np.where(disc >= 0, c / q, np.inf)


def _sphere(o, d, obj, t_min):
    """|o + t d|² = r²: the nearest root above t_min (the cancellation-free pair q/a, c/q)."""
    return _nearest(t_min, *_roots(o, d, obj.radius))


def _box(o, d, obj, t_min):
    """Slabs |x_i| ≤ h_i: enter at the largest near plane, leave at the smallest far plane."""
    half = np.asarray(obj.size or (2.0, 2.0, 2.0)) / 2
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-half - o) / d, (half - o) / d
    # fmin/fmax skip the NaN of 0/0 (a ray in a slab's boundary plane): that slab does not limit t.
    near = np.fmax.reduce(np.fmin(t1, t2), axis=1)
    far = np.fmin.reduce(np.fmax(t1, t2), axis=1)
    inside = near <= far
    return _nearest(t_min, np.where(inside, near, np.inf), np.where(inside, far, np.inf))


def _box_normal(p, obj):
    half = np.asarray(obj.size or (2.0, 2.0, 2.0)) / 2
    axis = np.argmax(np.abs(p) / half, axis=1)  # the face the point lies on
    normal = np.zeros_like(p)
    normal[np.arange(len(p)), axis] = np.sign(p[np.arange(len(p)), axis])
    return normal


def _plane(o, d, obj, t_min):
    """y = 0 within |x| ≤ w/2, |z| ≤ depth/2."""
    width, depth = obj.size or (2.0, 2.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -o[:, 1] / d[:, 1]
    p = o + np.where(np.isfinite(t), t, 0)[:, None] * d
    on = (np.abs(p[:, 0]) <= width / 2) & (np.abs(p[:, 2]) <= depth / 2) & (t > t_min)
    return np.where(on, t, np.inf)


def _cylinder(o, d, obj, t_min):
    """Side x² + y² = r², |z| ≤ h/2, and the two caps z = ±h/2, x² + y² ≤ r²."""
    r, h = obj.radius, obj.height / 2
    candidates = []
    with np.errstate(divide="ignore", invalid="ignore"):
        for t in _roots(o[:, :2], d[:, :2], r):
            z = o[:, 2] + t * d[:, 2]
            candidates.append(np.where((np.abs(z) <= h) & np.isfinite(t), t, np.inf))
        for cap in (-h, h):
            t = (cap - o[:, 2]) / d[:, 2]
            x, y = o[:, 0] + t * d[:, 0], o[:, 1] + t * d[:, 1]
            candidates.append(np.where((x * x + y * y <= r * r) & np.isfinite(t), t, np.inf))
    return _nearest(t_min, *candidates)


def _cylinder_normal(p, obj):
    # A cap point lies at |z| = h/2 (to rounding); a side point at radius r.
    side_gap = np.abs(np.hypot(p[:, 0], p[:, 1]) - obj.radius)
    cap_gap = np.abs(np.abs(p[:, 2]) - obj.height / 2)
    cap = cap_gap < side_gap
    normal = np.column_stack([p[:, 0], p[:, 1], np.zeros(len(p))])
    normal[cap] = np.column_stack([np.zeros(cap.sum()), np.zeros(cap.sum()), np.sign(p[cap, 2])])
    return normal


def _torus(o, d, obj, t_min):
    """(|p|² + R² − r²)² = 4R²(x² + y²), the tube around the circle of radius R in the local x–y plane.

    With a unit direction u and the parameter τ measured from the point q closest to the centre
    (q·u = 0) the quartic has no cubic term: τ⁴ + (2e − 4R²a₂)τ² − 4R²a₁τ + e² − 4R²a₀, e = |q|² + R² − r².
    Its roots are the eigenvalues of the companion matrix, polished by Newton steps.
    """
    big, small = obj.major_radius, obj.minor_radius
    length = np.linalg.norm(d, axis=1)
    u = d / length[:, None]
    s0 = -np.einsum("ij,ij->i", o, u)
    q = o + s0[:, None] * u
    t = np.full(len(o), np.inf)
    near = np.linalg.norm(q, axis=1) < big + small  # rays that miss the bounding sphere need no quartic
    if near.any():
        qn, un = q[near], u[near]
        e = np.einsum("ij,ij->i", qn, qn) + big * big - small * small
        a2 = un[:, 0] ** 2 + un[:, 1] ** 2
        a1 = 2 * (qn[:, 0] * un[:, 0] + qn[:, 1] * un[:, 1])
        a0 = qn[:, 0] ** 2 + qn[:, 1] ** 2
        c2, c1, c0 = 2 * e - 4 * big * big * a2, -4 * big * big * a1, e * e - 4 * big * big * a0
        companion = np.zeros((len(qn), 4, 4))
        companion[:, 0, 1], companion[:, 0, 2], companion[:, 0, 3] = -c2, -c1, -c0
        companion[:, 1, 0] = companion[:, 2, 1] = companion[:, 3, 2] = 1.0
        roots = np.linalg.eigvals(companion)
        # A near-double root (a grazing ray) comes out with an imaginary part of about √ε × the size.
        tau = np.where(np.abs(roots.imag) <= 1e-6 * (big + small), roots.real, np.nan)
        for _ in range(3):
            value = ((tau * tau + c2[:, None]) * tau + c1[:, None]) * tau + c0[:, None]
            slope = (4 * tau * tau + 2 * c2[:, None]) * tau + c1[:, None]
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(slope != 0, value / slope, 0.0)
            tau = tau - np.where(np.isfinite(step), step, 0.0)
        s = s0[near, None] + tau
        s = np.where(np.isfinite(s) & (s > t_min * length[near, None]), s, np.inf)
        t[near] = s.min(axis=1) / length[near]
    return t


def _torus_normal(p, obj):
    ring = np.hypot(p[:, 0], p[:, 1])
    # The nearest point of the tube's centre circle; the normal points from it to p.
    centre = obj.major_radius * p[:, :2] / np.where(ring > 0, ring, 1.0)[:, None]
    return np.column_stack([p[:, 0] - centre[:, 0], p[:, 1] - centre[:, 1], p[:, 2]])


def _nearest(t_min, *candidates):
    """The smallest candidate above t_min, inf if none."""
    stacked = np.stack(candidates)
    return np.where(stacked > t_min, stacked, np.inf).min(axis=0)


INTERSECT = {"icosphere": _sphere, "uv_sphere": _sphere, "box": _box, "plane": _plane,
             "cylinder": _cylinder, "torus": _torus}
NORMAL = {"icosphere": lambda p, obj: p, "uv_sphere": lambda p, obj: p, "box": _box_normal,
          "plane": lambda p, obj: np.broadcast_to([0.0, 1.0, 0.0], p.shape).copy(),
          "cylinder": _cylinder_normal, "torus": _torus_normal}


class ExactScene:
    """The scene's analytic objects, each with its world_from_object affine map."""

    def __init__(self, scene: Scene):
        for index, obj in enumerate(scene.objects):
            if obj.shape not in INTERSECT:  # a mesh file: the oracle knows the closed forms it was written for
                raise SceneError(f'"{obj.shape}" has no closed form; use --fine N',
                                 scene.origin.at("objects", index, "shape"))
        self.objects = scene.objects
        # world = linear · local + translate, linear = R S (geometry.place); rows map object → world.
        self.linear = [rotation(obj) @ np.diag(obj.scale) for obj in scene.objects]
        self.inverse = [np.linalg.inv(m) for m in self.linear]
        self.translate = [np.asarray(obj.translate, np.float64) for obj in scene.objects]
        low, high = self.bounds()
        # The same half-extent intersect.unit_frame takes from the mesh (it floors d in 1/d²).
        self.scale = float((high - low).max()) / 2 or 1.0

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The exact world bounding box, from each shape's support function under its affine map."""
        lows, highs = [], []
        for obj, m, t in zip(self.objects, self.linear, self.translate):
            if obj.shape in ("icosphere", "uv_sphere"):
                extent = obj.radius * np.linalg.norm(m, axis=1)
            elif obj.shape == "box":
                extent = np.abs(m) @ (np.asarray(obj.size or (2.0, 2.0, 2.0)) / 2)
            elif obj.shape == "plane":
                width, depth = obj.size or (2.0, 2.0)
                extent = np.abs(m[:, 0]) * width / 2 + np.abs(m[:, 2]) * depth / 2
            elif obj.shape == "cylinder":  # a disc in local x–y swept along z
                extent = obj.radius * np.hypot(m[:, 0], m[:, 1]) + np.abs(m[:, 2]) * obj.height / 2
            else:  # torus: the centre circle plus a ball of the minor radius
                extent = obj.major_radius * np.hypot(m[:, 0], m[:, 1]) + obj.minor_radius * np.linalg.norm(m, axis=1)
            lows.append(t - extent)
            highs.append(t + extent)
        return np.min(lows, axis=0), np.max(highs, axis=0)

    def closest(self, origins: np.ndarray, directions: np.ndarray, t_min: float = 0.0):
        """Nearest exact hit: t (N,) (inf on a miss), object index (N,) (−1), world point and unit normal (N, 3).

        `directions` are unit in world space; an affine map keeps t, so t is the world distance.
        """
        best = np.full(len(origins), np.inf)
        which = np.full(len(origins), -1)
        normal = np.zeros_like(origins)
        for index, obj in enumerate(self.objects):
            inverse = self.inverse[index]
            local_o = (origins - self.translate[index]) @ inverse.T
            local_d = directions @ inverse.T
            t = INTERSECT[obj.shape](local_o, local_d, obj, t_min)
            closer = t < best
            if closer.any():
                local_p = local_o[closer] + t[closer, None] * local_d[closer]
                best[closer], which[closer] = t[closer], index
                # Normals are covectors: world = (linear)^-T · local, i.e. local @ inverse as rows.
                normal[closer] = NORMAL[obj.shape](local_p, obj) @ inverse
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        normal = normal / np.where(length > 0, length, 1.0)
        points = origins + np.where(np.isfinite(best), best, 0)[:, None] * directions
        return best, which, points, normal


# ---------------------------------------------------------------- the illumination model, float64 numpy

def specular_power(x: np.ndarray, f: np.ndarray) -> np.ndarray:
    """max(x, 0)^f with illumination.specular_power's limits: f = 0 → 1 where x > 0; f = inf → x ≥ 1."""
    out = np.zeros_like(x)
    positive = x > 0
    out[positive & (f == 0)] = 1.0
    ordinary = positive & (f > 0) & np.isfinite(f)
    out[ordinary] = x[ordinary] ** f[ordinary]
    mirror = positive & np.isinf(f)
    out[mirror] = (x[mirror] >= 1).astype(np.float64)
    return out


def illuminate_exact(scene: Scene, points, normals, to_viewer, material_rows, visible, scale: float):
    """The four terms (ambient, diffuse, specular, emission), each (M, 3) float64, at M points.

        I = k_e + I_a k_a + Σ_lights f_att [ I_a,light k_a + vis (I_d k_d max(l·n, 0) + I_s k_s S) ]

    as the shading kernel evaluates it (illumination.py; scene format, "Meaning"). material_rows (M, 13): ka, kd,
    ks, ke, f; visible (M, K) bool (all True in local mode); normals already flipped toward the viewer.
    """
    ka, kd, ks, ke, f = (material_rows[:, 0:3], material_rows[:, 3:6], material_rows[:, 6:9],
                         material_rows[:, 9:12], material_rows[:, 12])
    ambient = np.asarray(scene.ambient) * ka
    diffuse, specular = np.zeros_like(ka), np.zeros_like(ka)
    for k, light in enumerate(scene.lights):
        if light.type == "point":
            to_light = np.asarray(light.position) - points
            distance = np.linalg.norm(to_light, axis=1)
            # A light within the distance floor has no direction the hit point's rounding does not decide:
            # head-on (l = n), as the kernel does.
            away = distance > MIN_DISTANCE * scale
            to_light = np.where(away[:, None], to_light / np.where(away, distance, 1)[:, None], normals)
        else:
            distance = np.zeros(len(points))
            to_light = np.broadcast_to(-np.asarray(light.direction) / np.linalg.norm(light.direction), points.shape)
        weight = np.ones(len(points))
        if light.type == "point" and light.attenuation == "inverse_square":
            # d floored at MIN_DISTANCE × the scene's half-extent, as shading.prepare_shading does.
            weight = 1 / np.maximum(distance ** 2, (MIN_DISTANCE * scale) ** 2)
        elif light.type == "point" and light.attenuation != "none":
            c, l, q = light.attenuation  # noqa: E741
            # min(1, 1/x) as 1/max(1, x), as the kernel: no 1/0 where x = 0 (c = 0 at d = 0).
            weight = 1 / np.maximum(1.0, c + l * distance + q * distance ** 2)
        ambient = ambient + weight[:, None] * np.asarray(light.ambient) * ka
        n_dot_l = np.einsum("ij,ij->i", normals, to_light)
        lit = (n_dot_l > UNLIT) & visible[:, k]  # S = 0 (and no diffuse) where l·n ≤ 0 (to rounding) or in shadow
        diffuse += np.where(lit, weight * n_dot_l, 0)[:, None] * np.asarray(light.diffuse) * kd
        if scene.render.specular == SpecularModel.PHONG:
            reflected = 2 * n_dot_l[:, None] * normals - to_light
            x = np.einsum("ij,ij->i", reflected, to_viewer)
        else:
            half = to_light + to_viewer
            length = np.linalg.norm(half, axis=1)
            x = np.where(length > 0, np.einsum("ij,ij->i", normals, half) / np.where(length > 0, length, 1), 0.0)
        s = np.where(lit, weight * specular_power(x, f), 0)
        specular += s[:, None] * np.asarray(light.specular) * ks
    return ambient, diffuse, specular, ke


# ---------------------------------------------------------------- rays and the image

def sample_rays(rig: CameraFrame, width: int, height: int, samples: int, row0: int, row1: int):
    """float64 world origins and unit directions of rows [row0, row1): pixel (i, j) with n × n samples has
    rays through raster (i + (a + ½)/n, j + (b + ½)/n), row 0 at the top, ray k → pixel k // n², cell k % n²."""
    cells = (np.arange(samples) + 0.5) / samples
    rows = np.arange(row0, row1)
    # Order: row, column, sub-row b, sub-column a (ray k → pixel k // n², cell k % n²).
    y = 1.0 - 2.0 * (rows[:, None, None, None] + cells[None, None, :, None]) / height
    x = 2.0 * (np.arange(width)[None, :, None, None] + cells[None, None, None, :]) / width - 1.0
    y, x = np.broadcast_arrays(y, x)
    sx, sy = (x * rig.half_width).reshape(-1, 1), (y * rig.half_height).reshape(-1, 1)
    if rig.orthographic:
        origins = rig.eye + sx * rig.right + sy * rig.up
        directions = np.broadcast_to(rig.forward, origins.shape).copy()
    else:
        directions = rig.forward + sx * rig.right + sy * rig.up
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        origins = np.broadcast_to(rig.eye, directions.shape).copy()
    return origins, directions


def material_table(scene: Scene) -> np.ndarray:
    """(objects, 13) float64: each object's ka, kd, ks, ke, shininess."""
    return np.array([[*m.ka, *m.kd, *m.ks, *m.ke, m.shininess] for m in map(scene.material_of, scene.objects)])


def analytic_reference(scene: Scene) -> ReferenceImage:
    """The scene on its exact surfaces, float64: see the module docstring. SceneError for a mesh object."""
    exact = ExactScene(scene)
    rig = camera_frame(scene)
    opts = scene.render
    width, height, n = opts.width, opts.height, opts.samples
    per_pixel = n * n
    materials = material_table(scene)
    maps = scene_maps(scene)
    textured = any(maps.values())
    image = np.zeros((height, width, 3))
    specular_image = np.zeros((height, width, 3))
    coverage = np.zeros((height, width))
    fixed_view = opts.viewer == Viewer.INFINITE or rig.orthographic  # one v = −forward for the image
    rows_per_tile = max(1, TILE_SAMPLES // (width * per_pixel))
    for row0 in range(0, height, rows_per_tile):
        row1 = min(row0 + rows_per_tile, height)
        origins, directions = sample_rays(rig, width, height, n, row0, row1)
        t, which, points, normals = exact.closest(origins, directions)
        hit = np.isfinite(t)
        rgb = np.broadcast_to(np.asarray(opts.background, np.float64), origins.shape).copy()
        spec = np.zeros_like(rgb)
        if hit.any():
            p, nrm, d = points[hit], normals[hit], directions[hit]
            # Two-sided: a back-facing hit is shaded with the normal turned toward the viewer.
            if opts.two_sided:
                nrm = np.where((np.einsum("ij,ij->i", nrm, d) > 0)[:, None], -nrm, nrm)
            if fixed_view:
                to_viewer = np.broadcast_to(-rig.forward, p.shape)
            else:
                to_viewer = rig.eye - p
                to_viewer = to_viewer / np.linalg.norm(to_viewer, axis=1, keepdims=True)
            visible = light_visibility(exact, scene, p, nrm) if opts.mode.value == "global" else \
                np.ones((len(p), len(scene.lights)), bool)
            rows = materials[which[hit]]
            if textured:
                rows = textured_rows(scene, exact, maps, rows, which[hit], p)
            terms = illuminate_exact(scene, p, nrm, to_viewer, rows, visible, exact.scale)
            rgb[hit] = sum(terms)
            spec[hit] = terms[2]
        shape = (row1 - row0, width, per_pixel)
        image[row0:row1] = rgb.reshape(*shape, 3).mean(axis=2)
        specular_image[row0:row1] = spec.reshape(*shape, 3).mean(axis=2)
        coverage[row0:row1] = hit.reshape(shape).mean(axis=2)
    return ReferenceImage(image, specular_image, coverage, "analytic")


def light_visibility(exact: ExactScene, scene: Scene, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(M, K) bool: an exact shadow ray from each point reaches light k (global mode).

    The origin is lifted SHADOW_OFFSET × the scene's size off the surface on the light's side, so
    the ray does not find the surface it leaves; the true surface has no shadow terminator to fix.
    """
    offset = SHADOW_OFFSET * exact.scale
    visible = np.ones((len(points), len(scene.lights)), bool)
    for k, light in enumerate(scene.lights):
        if light.type == "point":
            to_light = np.asarray(light.position) - points
            distance = np.linalg.norm(to_light, axis=1)
            to_light = to_light / np.where(distance > 0, distance, 1)[:, None]
        else:
            distance = np.full(len(points), np.inf)
            to_light = np.broadcast_to(-np.asarray(light.direction) / np.linalg.norm(light.direction), points.shape)
        side = np.sign(np.einsum("ij,ij->i", normals, to_light))
        origin = points + (offset * side)[:, None] * normals
        t, _, _, _ = exact.closest(origin, np.ascontiguousarray(to_light))
        visible[:, k] = t >= distance - offset
    return visible


# ---------------------------------------------------------------- textured surfaces (closed form)

def ramp(u, v) -> np.ndarray:
    """A linear colour ramp over texture space (…, 3): bilinear filtering and every box-filtered mip level
    reproduce a linear function of the texel centres exactly, so a texture of these values has a closed form
    away from the wrap seam."""
    u, v = np.asarray(u, np.float64), np.asarray(v, np.float64)
    return np.stack([0.2 + 0.6 * u, 0.1 + 0.5 * v, 0.3 + 0.2 * u + 0.3 * v], axis=-1)


def exact_uv(shape: str, points: np.ndarray, size=(2.0, 2.0)) -> np.ndarray:
    """The exact texture coordinates (…, 2) of object-frame points on a built-in shape: plane (x–z, size
    (w, d)): u = x/w + ½, v = ½ − z/d; sphere about z: u = atan2(y, x)/2π in [0, 1), v = ½ + asin(z/|p|)/π."""
    points = np.asarray(points, np.float64)
    if shape == "plane":
        return np.stack([points[..., 0] / size[0] + 0.5, 0.5 - points[..., 2] / size[1]], axis=-1)
    r = np.linalg.norm(points, axis=-1)
    return np.stack([(np.arctan2(points[..., 1], points[..., 0]) / (2 * np.pi)) % 1.0,
                     0.5 + np.arcsin(np.clip(points[..., 2] / r, -1, 1)) / np.pi], axis=-1)


def textured_plane_colour(u, v, kd, ka, ambient: float, diffuse: float, cosine: float = 1.0) -> np.ndarray:
    """A plane whose k_d map (and so k_a's) is ramp(u, v), lit by one light of I_d = `diffuse` at the angle
    of `cosine`, scene ambient I_a = `ambient`, no specular: (I_a k_a + I_d cos k_d) · ramp(u, v)."""
    return (ambient * np.asarray(ka) + diffuse * cosine * np.asarray(kd)) * ramp(u, v)


def textured_ambient_reference(scene: Scene, ka) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) float64 colour of a scene of ONE built-in sphere or plane (not rotated or scaled) whose k_a
    map is ramp(u, v), lit by scene ambient only: I_a k_a ramp(u, v) at the exact hit's exact UVs; and (H, W)
    u of each hit (NaN on a miss), so a test can keep away from the seam. One ray per pixel centre."""
    exact = ExactScene(scene)
    obj = scene.objects[0]
    rig = camera_frame(scene)
    width, height = scene.render.width, scene.render.height
    origins, directions = sample_rays(rig, width, height, 1, 0, height)
    _, which, points, _ = exact.closest(origins, directions)
    local = points - exact.translate[0]
    uv = exact_uv("plane", local, obj.size or (2.0, 2.0)) if obj.shape == "plane" else exact_uv("sphere", local)
    colour = np.asarray(scene.ambient) * np.asarray(ka) * ramp(uv[:, 0], uv[:, 1])
    hit = which >= 0
    colour[~hit] = 0
    u = np.where(hit, uv[:, 0], np.nan)
    return colour.reshape(height, width, 3), u.reshape(height, width)


# ---------------------------------------------------------------- colour maps on the exact surfaces

def srgb_decode(values: np.ndarray) -> np.ndarray:
    """The sRGB transfer function's inverse (IEC 61966-2-1), on values in [0, 1]."""
    return np.where(values <= 0.04045, values / 12.92, ((values + 0.055) / 1.055) ** 2.4)


def read_map(path, colour: str) -> np.ndarray:
    """(H, W, 3) float64 RGB of an image file, read with OpenImageIO, for a scene whose render.colour is
    `colour` (the scene format): an integer (8-bit) image is sRGB-encoded, so "linear" decodes it and "display"
    takes it as stored; a float image is linear values, taken as stored either way. Its own reading: nothing
    of the renderer's decoding is shared."""
    import OpenImageIO as oiio
    stored = oiio.ImageSpec()  # a PNG's colour as written, not multiplied by its alpha (OpenImageIO's default)
    stored.attribute("oiio:UnassociatedAlpha", 1)
    buffer = oiio.ImageBuf(str(path), 0, 0, stored)
    spec = buffer.spec()
    pixels = np.asarray(buffer.get_pixels(oiio.FLOAT), np.float64).reshape(spec.height, spec.width, -1)
    if pixels.shape[2] < 3:
        pixels = np.repeat(pixels[:, :, :1], 3, axis=2)
    pixels = pixels[:, :, :3]
    if spec.format.basetype in (oiio.HALF, oiio.FLOAT, oiio.DOUBLE) or colour != "linear":
        return pixels
    return srgb_decode(pixels)


def scene_maps(scene: Scene) -> dict[int, dict]:
    """object index → {"ka" | "kd" | "ke": ((H, W, 3) texels, wrap)} of the maps its material names (the k_a
    map is the k_d map unless given). SceneError for a textured shape with no closed-form UVs here."""
    found, cache = {}, {}
    for index, obj in enumerate(scene.objects):
        material = scene.material_of(obj)
        given = {key: getattr(material, f"{key}_map", None) for key in ("ka", "kd", "ke")}
        if given["ka"] is None:
            given["ka"] = given["kd"]
        maps = {}
        for key, value in given.items():
            if value is None:
                continue
            path = scene.resolve(value.path)
            if path not in cache:
                cache[path] = read_map(path, scene.render.colour)
            maps[key] = (cache[path], value.wrap)
        if maps and obj.shape not in ("plane", "icosphere", "uv_sphere"):
            raise SceneError(f"the analytic reference has exact texture coordinates for planes and spheres only, not "
                             f"a textured {obj.shape}; use --fine N", scene.origin.at("objects", index))
        found[index] = maps
    return found


def _wrapped(i: np.ndarray, n: int, wrap: str) -> np.ndarray:
    if wrap == "clamp":
        return np.clip(i, 0, n - 1)
    if wrap == "mirror":
        p = np.mod(i, 2 * n)
        return np.where(p < n, p, 2 * n - 1 - p)
    return np.mod(i, n)


def bilinear(texels: np.ndarray, wrap: str, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(M, 3) bilinear lookups of texels (H, W, 3) at (u, v), v up (row 0 is v = 1), texel centres at
    ((x + ½)/W, 1 − (y + ½)/H). No mip level: the reference is the texture at the point itself."""
    h, w = texels.shape[:2]
    x, y = u * w - 0.5, (1 - v) * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    ax, ay = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    xa, xb = _wrapped(x0, w, wrap), _wrapped(x0 + 1, w, wrap)
    ya, yb = _wrapped(y0, h, wrap), _wrapped(y0 + 1, h, wrap)
    return ((1 - ay) * ((1 - ax) * texels[ya, xa] + ax * texels[ya, xb])
            + ay * ((1 - ax) * texels[yb, xa] + ax * texels[yb, xb]))


def textured_rows(scene: Scene, exact: ExactScene, maps: dict, rows: np.ndarray, which: np.ndarray,
                  points: np.ndarray) -> np.ndarray:
    """Material rows (M, 13) at M hits with each object's maps applied at the exact UVs of its exact hit
    (exact_uv in the object's own frame): k_a, k_d, k_e multiplied; k_s never."""
    rows = rows.copy()
    for index, found in maps.items():
        here = which == index
        if not found or not here.any():
            continue
        obj = scene.objects[index]
        local = (points[here] - exact.translate[index]) @ exact.inverse[index].T
        uv = exact_uv("plane", local, obj.size or (2.0, 2.0)) if obj.shape == "plane" else exact_uv("sphere", local)
        for key, column in (("ka", 0), ("kd", 3), ("ke", 9)):
            if key in found:
                texels, wrap = found[key]
                rows[here, column:column + 3] *= bilinear(texels, wrap, uv[:, 0], uv[:, 1])
    return rows
