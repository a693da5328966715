"""The stability suite: stiff and extreme inputs, each case a property that can fail and a measured figure.

`raycast-phong stability` runs every case on the installed package and prints the table;
tests/tools/test_stability.py runs the same functions. Images are small (tens of pixels) so the suite takes
seconds. docs/stability.md has the table and pictures of the instructive cases.
"""

from __future__ import annotations

import atexit
import functools
import itertools
import math
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..codes import StageName
from ..geometry.build import build_geometry
from ..records import RenderPlan, Stage
from ..renderer.frame import render
from ..renderer.intersect import Accelerator, unit_frame
from ..renderer.plan import F32_SHININESS_LIMIT, build_plan
from ..scene.schema import Scene, SceneError, validate_scene
from ..tolerances import INTENSITY_LIMIT
from ..values.messages import dotted


@dataclass(frozen=True)
class CaseResult:
    """One row of the report: the property, what was measured, and the number the verdict rests on against its
    limit (value ≤ limit, or ≥ when `at_least`); None for a property that is a yes or no (a warning given)."""
    case: str
    property: str
    figure: str
    passed: bool
    seconds: float = 0.0
    value: float | None = None
    limit: float | None = None
    at_least: bool = False

    @property
    def margin(self) -> float | None:
        """How many times the value is within its limit (limit / value, or value / limit for `at_least`): 1 at the
        limit, below 1 failing, inf for a value of 0 under a limit."""
        if self.value is None or self.limit is None:
            return None
        top, bottom = (self.value, self.limit) if self.at_least else (self.limit, self.value)
        return math.inf if bottom == 0 else top / bottom


CASES: dict[str, Callable[[], CaseResult]] = {}


def case(function: Callable[[], CaseResult]) -> Callable[[], CaseResult]:
    CASES[function.__name__] = function
    return function


def run_all(names: list[str] | None = None,
            progress: Callable[[int, int, str], None] | None = None) -> list[CaseResult]:
    """Run the named cases (all by default), timing each; progress(done, total, name of the next case, or "done")
    is called before each case and after the last."""
    results = []
    names = names or list(CASES)
    progress = progress or (lambda done, total, name: None)
    for done, name in enumerate(names):
        progress(done, len(names), name)
        start = time.perf_counter()
        result = CASES[name]()
        results.append(replace(result, seconds=time.perf_counter() - start))
    progress(len(names), len(names), "done")
    return results


# ---------------------------------------------------------------- scenes

def sphere_scene(shininess: float = 32.0, subdivisions: int = 4, size: int = 48, **render_keys) -> Scene:
    return validate_scene({
        "render": {"width": size, "height": size, "shading": "phong", **render_keys},
        "camera": {"position": [0, 0, 4], "fov": 40},
        "ambient": 0.1,
        "lights": [{"type": "point", "position": [2, 2, 3], "diffuse": 0.8, "specular": 1.0}],
        "materials": {"m": {"ka": 1, "kd": 0.6, "ks": 0.5, "shininess": shininess}},
        "objects": [{"shape": "icosphere", "subdivisions": subdivisions, "material": "m"}],
    }, source="stability")


def with_precision(plan: RenderPlan, float64: bool) -> RenderPlan:
    """The plan with its shading precision forced (to measure what float32 would have done)."""
    stages = tuple(Stage(s.name, float64, "forced by the stability suite") if s.name == StageName.FLOAT64_SHADING else s
                   for s in plan.stages)
    return replace(plan, stages=stages)


def both_precisions(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """The scene's image shaded in float32 and in float64, each forced whatever the plan would choose."""
    plan = build_plan(scene)
    return tuple(render(scene, plan=with_precision(plan, float64)).image for float64 in (False, True))


def head_on_plane(light: dict, material: dict, ambient: float, **render_keys) -> Scene:
    """A 4 × 4 plane seen head-on by a 3 × 3 orthographic view 1 high, an infinite viewer (v = n), one light."""
    return validate_scene({
        "render": {"width": 3, "height": 3, "viewer": "infinite", **render_keys},
        "camera": {"type": "orthographic", "position": [0, 0, 5], "view_height": 1.0},
        "ambient": ambient,
        "lights": [light],
        "materials": {"m": material},
        "objects": [{"shape": "plane", "size": [4, 4], "rotate": [90, 0, 0], "material": "m"}],
    }, source="stability")


# ---------------------------------------------------------------- 1. specular exponent

EXPONENTS = (0.0, 1e-6, 1.0, 128.0, 1e3, 1e4, 1e6, math.inf)


@case
def specular_exponent() -> CaseResult:
    images = {f: render(sphere_scene(f, precision="float64")).image for f in EXPONENTS}
    finite = all(np.isfinite(image).all() and image.min() >= 0 for image in images.values())
    near_mirror = int((np.abs(images[1e6] - images[math.inf]).max(axis=2) > 1e-3).sum())
    return CaseResult("specular exponent", "every f in {0, 1e-6, 1, 128, 1e3, 1e4, 1e6, inf}: finite, ≥ 0; "
                      "f = 1e6 and inf differ on ≤ 5 pixels",
                      f"{near_mirror} pixel(s) differ between f = 1e6 and inf", finite and near_mirror <= 5,
                      value=near_mirror, limit=5)


def float32_highlight_error(shininess: float) -> tuple[float, float]:
    """Largest |float32 − float64| of S = (v·r)^f over 16 angles θ in [0.5, 1.5]/√f off the mirror
    direction (S from e^-1/8 to e^-9/8), on a plane under a directional light seen by an infinite
    viewer, float32 forced even above the limit (one angle alone may round luckily). Returns
    (largest absolute error, S at θ = 1/√f in float64)."""
    worst, middle = 0.0, 0.0
    for theta in np.linspace(0.5, 1.5, 16) / math.sqrt(shininess):
        # The light is θ/2 off the normal, so the reflected ray r is θ off the viewer's v = n.
        scene = head_on_plane({"type": "directional", "direction": [-math.sin(theta / 2), 0, -math.cos(theta / 2)],
                               "diffuse": 0}, {"ka": 0, "kd": 0, "ks": 1, "shininess": shininess}, 0, shading="phong")
        single, double = (float(image[1, 1, 0]) for image in both_precisions(scene))
        worst = max(worst, abs(single - double))
        middle = double if abs(theta * math.sqrt(shininess) - 1) < 0.04 else middle
    return worst, middle


@case
def float32_shininess_limit() -> CaseResult:
    errors = {f: float32_highlight_error(f)[0] for f in (1e3, 1e4, F32_SHININESS_LIMIT, 1e6, 1e7)}
    switched = build_plan(sphere_scene(1e6)).keeps(StageName.FLOAT64_SHADING)
    stays = not build_plan(sphere_scene(1e3)).keeps(StageName.FLOAT64_SHADING)
    figure = "forced float32 error near the highlight peak: " + ", ".join(f"{e:.0e} at f = {f:g}"
                                                                          for f, e in errors.items())
    return CaseResult("float32 and stiff highlights", f"above f = {F32_SHININESS_LIMIT:g} the plan shades in "
                      "float64; below it float32 stays within half an 8-bit step (1/512)", figure,
                      switched and stays and errors[1e4] < 1 / 512, value=errors[1e4], limit=1 / 512)


# ---------------------------------------------------------------- 2. stiff highlights under Gouraud

def gouraud_phong_peak_ratio(shininess: float, subdivisions: int = 1) -> float:
    """Peak specular of Gouraud over Phong shading on an icosphere (80 faces at 1 subdivision)."""
    peaks = []
    for model in ("gouraud", "phong"):
        scene = sphere_scene(shininess, subdivisions, size=96, shading=model, precision="float64")
        scene = scene.model_copy(update={"output": scene.output.model_copy(update={"path": "x.exr",
                                                                                    "aovs": ("specular",)})})
        peaks.append(render(scene).aovs["specular"].max())
    return float(peaks[0] / peaks[1])


@case
def stiff_gouraud() -> CaseResult:
    ratios = {f: gouraud_phong_peak_ratio(f) for f in (10.0, 100.0, 1000.0)}
    warned = {f: any("gouraud" in w and "subdivisions =" in w
                     for w in render(sphere_scene(f, 1, shading="gouraud")).plan.warnings) for f in ratios}
    figure = ", ".join(f"f = {f:g}: {r:.2g}" for f, r in ratios.items()) + " (Gouraud/Phong peak, 80 faces)"
    return CaseResult("stiff highlights under Gouraud", "the peak ratio falls with f and the plan warns with a "
                      "subdivision count when vertex normals are wider apart than 1/√f",
                      figure, ratios[10.0] > ratios[100.0] > ratios[1000.0] and all(warned.values()),
                      value=max(ratios[100.0] / ratios[10.0], ratios[1000.0] / ratios[100.0]), limit=1.0)


@case
def subpixel_highlight() -> CaseResult:
    scene = sphere_scene(1e5, subdivisions=5, size=32)
    warnings = render(scene).plan.warnings
    suggests = [w for w in warnings if "render.samples" in w]
    figure = "no warning"
    if suggests:
        width = suggests[0].split("about ")[1].split(" pixel")[0]
        advice = suggests[0].split("centres; ")[1]
        figure = f"f = 1e5 on a 32 px sphere: {width} px wide; plan: {advice}"
    return CaseResult("sub-pixel highlight", "a highlight narrower than a pixel is warned about with a sample count",
                      figure, bool(suggests))


# ---------------------------------------------------------------- 3. light at, on or inside the surface

def plane_with_light(distance: float, attenuation, precision: str = "float32",
                     sideways: tuple[float, float] = (0.0, 0.0)) -> Scene:
    """A 4 × 4 plane (half-extent 2) seen head-on, a point light `distance` above its centre, moved `sideways`."""
    return validate_scene({
        "render": {"width": 9, "height": 9, "shading": "phong", "precision": precision},
        "camera": {"type": "orthographic", "position": [0, 0, 5], "view_height": 1.0},
        "lights": [{"type": "point", "position": [*sideways, distance], "attenuation": attenuation}],
        "objects": [{"shape": "plane", "size": [4, 4], "rotate": [90, 0, 0]}],
    }, source="stability")


@case
def light_on_the_surface() -> CaseResult:
    worst, finite, head_on = 0.0, True, True
    for distance, sideways, attenuation, precision in itertools.product(
            (0.0, 1e-30, 1e-12, -1e-12), ((0.0, 0.0), (3e-7, -5e-7)), ("none", "inverse_square", [1.0, 0.5, 0.25]),
            ("float32", "float64")):
        image = render(plane_with_light(distance, attenuation, precision, sideways)).image
        finite &= bool(np.isfinite(image).all() and image.min() >= 0)
        worst = max(worst, float(image.max()))
        if attenuation == "inverse_square":
            # Inside the floor (2e-6 here) the light is head-on: f_att (kd + ks) at the centre.
            head_on &= abs(float(image[4, 4].max()) / LIGHT_ON_SURFACE_PEAK - 1) < 1e-5
    return CaseResult("light at, on or inside the surface", "d ∈ {0, 1e-30, ±1e-12}, on the axis and 6e-7 "
                      "sideways, every attenuation, both precisions: finite, ≥ 0; inside the 1/d² floor (1e-6 of "
                      "the scene size) the light is head-on, so the centre pixel is f_att (k_d + k_s) on any CPU",
                      f"largest pixel {worst:.3g}", finite and head_on, value=worst, limit=INTENSITY_LIMIT)


# f_att (I_d k_d + I_s k_s) with l = n = v: the floor d = 1e-6 × the plane's half-extent 2, the default light
# (I_d 0.8, I_s 1) and material (k_d 0.8, k_s 0.5); the ambient term is 1e-12 of it.
LIGHT_ON_SURFACE_PEAK = 1 / (2e-6) ** 2 * (0.8 * 0.8 + 1.0 * 0.5)


# ---------------------------------------------------------------- 4. grazing light and view

def centre_steps(scenes) -> tuple[np.ndarray, float]:
    """The centre pixels (float64) of a sequence of 3 × 3 renders and the largest step between successive ones."""
    values = np.array([render(scene).image[1, 1].astype(np.float64) for scene in scenes])
    return values, float(np.abs(np.diff(values, axis=0)).max())


@case
def grazing_light() -> CaseResult:
    """The light sweeps through the plane's horizon: the image is continuous and, past it, ambient only."""
    angles = np.linspace(89.0, 91.0, 81)  # degrees from the normal
    values, jump = centre_steps(head_on_plane(
        {"type": "directional", "direction": [-math.sin(math.radians(angle)), 0, -math.cos(math.radians(angle))]},
        {"ka": 1, "kd": 0.8, "ks": 0.5, "ke": 0.05, "shininess": 4}, 0.1, shading="phong") for angle in angles)
    beyond = values[angles >= 90.0]
    exact = bool(np.allclose(beyond, 0.1 + 0.05, atol=1e-7))
    # A step of 2/80 degrees moves l·n by ≈ 4.4e-4: continuity means no jump much larger than that.
    return CaseResult("grazing light", "a viewer along the normal (there the highlight is 0 at l·n = 0): continuous "
                      "through l·n = 0, never negative, ambient + emission exactly past it; an oblique viewer sees the "
                      "model's own step, its highlight cut at l·n = 0",
                      f"largest step {jump:.1e} per 0.025°", jump < 2e-3 and values.min() >= 0 and exact,
                      value=jump, limit=2e-3)


@case
def grazing_view() -> CaseResult:
    """The eye sinks toward a lit plane's horizon (v·n → 0): finite, ≥ 0, continuous in the angle."""
    angles = np.linspace(80.0, 89.99, 60)  # degrees between the view direction and the plane's normal
    values, jump = centre_steps(validate_scene({
        "render": {"width": 3, "height": 3, "shading": "phong"},
        "camera": {"type": "orthographic", "position": [5 * math.sin(a), 0, 5 * math.cos(a)],
                   "up": [0, 1, 0], "view_height": 0.01},
        "ambient": 0.1,
        "lights": [{"type": "point", "position": [-1, 0.5, 2]}],
        "materials": {"m": {"ka": 1, "kd": 0.8, "ks": 0.5, "shininess": 16}},
        "objects": [{"shape": "plane", "size": [4, 4], "rotate": [90, 0, 0], "material": "m"}],
    }, source="stability") for a in map(math.radians, angles))
    return CaseResult("grazing view", "the eye at 80° … 89.99° from the normal: finite, ≥ 0, continuous",
                      f"largest step {jump:.1e} per 0.17°", bool(np.isfinite(values).all()) and values.min() >= 0
                      and jump < 0.02, value=jump, limit=0.02)


# ---------------------------------------------------------------- 5. degenerate geometry

def write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def mesh_scene(path: Path, shading: str = "phong", **render_keys) -> Scene:
    return validate_scene({
        "render": {"width": 48, "height": 48, "shading": shading, **render_keys},
        "camera": {"position": [0.3, 0.4, 4], "fov": 40},
        "lights": [{"type": "point", "position": [2, 2, 3]}],
        "objects": [{"shape": "mesh", "path": path.name}],
    }, source=str(path), folder=path.parent)


def against_clean(clean: Path, *others: Path) -> tuple[float, list]:
    """The largest change of the mesh files `others`' images from `clean`'s (rendered once) under each shading
    model, and the others' render results."""
    models = ("flat", "gouraud", "phong")
    images = [render(mesh_scene(clean, model)).image for model in models]
    results = [render(mesh_scene(other, model)) for other in others for model in models]
    worst = max(float(np.abs(images[k % len(models)] - result.image).max()) for k, result in enumerate(results))
    return worst, results


@case
def degenerate_geometry() -> CaseResult:
    import trimesh
    sphere = trimesh.creation.icosphere(3)
    vertices, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    n = len(vertices)
    # Zero-area faces (a repeated corner, three collinear points), a needle with a 1e-9 edge, and
    # duplicate vertices: appended so the clean sphere's pixels must not change.
    extra_vertices = np.vstack([vertices[:3] * 0.5, vertices[0] + [1e-9, 0, 0], vertices[5]])
    extra_faces = np.array([[0, 0, 1], [n, n + 1, n + 2], [0, n + 3, 1], [5, n + 4, 6]])
    with tempfile.TemporaryDirectory() as folder:
        clean, dirty = Path(folder) / "clean.obj", Path(folder) / "dirty.obj"
        write_obj(clean, vertices, faces)
        write_obj(dirty, np.vstack([vertices, extra_vertices]), np.vstack([faces, extra_faces]))
        worst, results = against_clean(clean, dirty)
    finite = all(np.isfinite(result.image).all() for result in results)
    return CaseResult("degenerate geometry", "zero-area faces, a 1e-9 needle, duplicate vertices: no NaN, "
                      "no hole, the image of the clean mesh", f"max change {worst:.1e}", finite and worst < 1e-5,
                      value=worst, limit=1e-5)


# ---------------------------------------------------------------- 6. inconsistent winding

@case
def inconsistent_winding() -> CaseResult:
    import trimesh
    sphere = trimesh.creation.icosphere(3)
    faces = np.asarray(sphere.faces).copy()
    faces[::2] = faces[::2, ::-1]  # every other face wound the wrong way
    with tempfile.TemporaryDirectory() as folder:
        clean, mixed = Path(folder) / "clean.obj", Path(folder) / "mixed.obj"
        write_obj(clean, sphere.vertices, sphere.faces)
        write_obj(mixed, sphere.vertices, faces)
        worst, results = against_clean(clean, mixed)
    noted = results[-1].plan.keeps(StageName.WINDING_REPAIR)
    return CaseResult("inconsistent winding", "half the faces flipped: every model's image unchanged, "
                      "the plan says the winding was repaired", f"max change {worst:.1e}", worst < 1e-5 and noted,
                      value=worst, limit=1e-5)


def hovering_sheet_scene(height: float) -> Scene:
    """Global mode: a 1 × 1 sheet `height` above an 8 × 8 plane, a directional light 89° from the vertical. Seen
    from above, the row spans the sheet's edge (its first quarter), the strip of the plane the sheet shadows
    beyond it (tan 89° × height long: the middle half) and lit plane (the last quarter)."""
    angle = math.radians(89.0)
    band = height * math.tan(angle)
    centre = 0.5 + band / 2
    return validate_scene({"render": {"width": 64, "height": 4, "mode": "global"},
                           "camera": {"type": "orthographic", "position": [centre, 10, 0], "look_at": [centre, 0, 0],
                                      "up": [0, 0, -1], "view_height": band / 8},
                           "ambient": 0.1, "lights": [{"type": "directional",
                                                       "direction": [math.sin(angle), -math.cos(angle), 0]}],
                           "objects": [{"shape": "plane", "size": [8, 8]},
                                       {"shape": "plane", "size": [1, 1], "translate": [0, height, 0]}]},
                          source="stability")


@case
def hovering_sheet() -> CaseResult:
    """The shadow of a sheet 1e-3 down to 1e-6 of the scene's size above a plane: the share of the row in shadow
    (darker than the lit sheet and plane at either end), which is ½."""
    shares = {}
    for share in (1e-3, 1e-4, 1e-5, 1e-6):
        row = render(hovering_sheet_scene(8.0 * share)).image[2, :, 0]  # the scene is 8 across
        lit = max(float(row[0]), float(row[-1]))
        shares[share] = float((row < lit - 1e-3).mean())
    # The origin's offset (8 float32 roundings of the unit frame, 4.8e-7) lowers the sheet as the shadow ray sees
    # it by that much: at 1e-6 of the size (2e-6 in the unit frame) the strip is 76 % of its length.
    off = max(abs(v - 0.5) for k, v in shares.items() if k >= 1e-5)
    return CaseResult("hovering sheet", "global mode, a sheet 1e-3 … 1e-6 of the scene's size above a plane, the light "
                      "89° from the vertical: its shadow strip is half the row (within 2 of 64 pixels) down to 1e-5, "
                      "and at least ¾ of that at 1e-6 (the origin's offset is a quarter of the height there)",
                      ", ".join(f"{k:g}: {v:.2f}" for k, v in shares.items()), off <= 2 / 64 and shares[1e-6] >= 0.375,
                      value=off, limit=2 / 64)


@case
def triangle_soup() -> CaseResult:
    """An icosphere written as a soup (every triangle its own corners, rounded apart by 1e-12 and by 1e-7 of the
    size), with and without every third face flipped: each model's image against the welded mesh's."""
    import trimesh
    sphere = trimesh.creation.icosphere(3)
    rng = np.random.default_rng(3)
    with tempfile.TemporaryDirectory() as folder:
        clean, soups = Path(folder) / "clean.obj", []
        write_obj(clean, sphere.vertices, sphere.faces)
        for flip, jitter in itertools.product((0, 3), (1e-12, 1e-7)):
            corners = sphere.vertices[sphere.faces].reshape(-1, 3)
            corners = corners * (1 + jitter * rng.standard_normal(corners.shape))
            faces = np.arange(len(corners)).reshape(-1, 3)
            if flip:
                faces[::flip] = faces[::flip, ::-1]
            soups.append(Path(folder) / f"soup-{flip}-{jitter:g}.obj")
            write_obj(soups[-1], corners, faces)
        worst, results = against_clean(clean, *soups)
    noted = all(any("triangle soup" in note for note in result.plan.notes) for result in results)
    return CaseResult("triangle soup", "a soup whose copies of a point differ by 1e-12 or 1e-7 of the size, every "
                      "third face flipped or none: the welded mesh's image within 1e-3, and a note",
                      f"max change {worst:.1e}", worst < 1e-3 and noted, value=worst, limit=1e-3)


# ---------------------------------------------------------------- 7. scale and position

def placed_scene(scale: float, shift: float, mode: str, **render_keys) -> Scene:
    def at(p):
        return [scale * c + shift for c in p]

    return validate_scene({
        "render": {"width": 48, "height": 48, "mode": mode, "shading": "phong", **render_keys},
        "camera": {"position": at([0.5, 1.5, 4]), "look_at": at([0, 0, 0]), "fov": 40},
        "lights": [{"type": "point", "position": at([2, 3, 2])}],
        "objects": [{"shape": "icosphere", "subdivisions": 2, "radius": scale, "translate": at([0, 0.3, 0])},
                    {"shape": "plane", "size": [4 * scale, 4 * scale], "translate": at([0, -1, 0])}],
    }, source="stability")


SCALES = (1e-6, 1e-3, 1.0, 1e3, 1e6)


@case
def scale_and_position() -> CaseResult:
    """render(s·scene + t) = render(scene): max difference, and the share of pixels above 1e-3."""
    worst_share, worst = 0.0, 0.0
    for mode in ("local", "global"):
        reference = render(placed_scene(1.0, 0.0, mode)).image
        for scale in SCALES:
            for shift in (0.0, 1e6 * 4 * scale):  # up to 1e6 × the scene size away
                image = render(placed_scene(scale, shift, mode)).image
                difference = np.abs(image - reference).max(axis=2)
                worst = max(worst, float(difference.max()))
                worst_share = max(worst_share, float((difference > 1e-3).mean()))
    return CaseResult("scale and position", "s from 1e-6 to 1e6, shifts up to 1e6 × the scene size, local and "
                      "global: ≤ 1 % of pixels (silhouettes, shadow edges) off by more than 1e-3",
                      f"{worst_share:.2%} of pixels off by > 1e-3; largest difference {worst:.1e}",
                      worst_share <= 0.01, value=worst_share, limit=0.01)


# ---------------------------------------------------------------- 8. watertightness

def far_scene(distance: float, projection: str) -> Scene:
    """A sphere seen from `distance` × its radius along (0.3, 0.2, 1), framed the same at every distance: a
    perspective camera's field of view shrinks with the distance, an orthographic view stays 2.6 high."""
    camera = {"type": projection, "position": [0.3 * distance, 0.2 * distance, distance], "look_at": [0, 0, 0]}
    if projection == "perspective":
        camera["fov"] = math.degrees(2 * math.atan(1.3 / (distance * math.sqrt(1.13))))
    else:
        camera["view_height"] = 2.6
    return validate_scene({"render": {"width": 64, "height": 64}, "camera": camera,
                           "objects": [{"shape": "icosphere", "subdivisions": 4}],
                           "lights": [{"type": "point", "position": [3, 4, 6]}]}, source="stability")


FAR = (1e3, 1e5, 1e6, 1e7, 1e9)


@case
def far_camera() -> CaseResult:
    """A sphere from 1e3 to 1e9 radii away, perspective and orthographic, against the orthographic view from 1e3:
    the largest pixel difference (a float32 origin 1e6 sizes away merged the sphere's front and back)."""
    reference = render(far_scene(1e3, "orthographic")).image
    worst = {(d, p): float(np.abs(render(far_scene(d, p)).image - reference).max())
             for d in FAR for p in ("perspective", "orthographic")}
    far = max(value for (d, p), value in worst.items() if d > 1e3 or p == "orthographic")
    return CaseResult("far camera", "the camera 1e3 … 1e9 scene sizes away (perspective and orthographic): no pixel "
                      "off by more than 0.01 from the near orthographic view",
                      f"largest difference {far:.1e} (perspective at 1e3, the projection's own: "
                      f"{worst[(1e3, 'perspective')]:.1e})", far <= 0.01, value=far, limit=0.01)


def light_in_plane_scene(precision: str, side: float = -1.0) -> Scene:
    """A plane tilted 30° about x, its point light exactly in its plane (3 along it, 0.5 across), shininess 1:
    n·l is rounding alone. side −1 puts the light beyond the plane from the viewer, where a highlight would show."""
    tilt = math.radians(30.0)
    along = np.array([0.0, -math.sin(tilt), math.cos(tilt)])  # in the plane rotate = [30, 0, 0] makes
    light = (side * 3.0 * along + [0.5, 0.0, 0.0]).tolist()
    return validate_scene({"render": {"width": 64, "height": 64, "precision": precision},
                           "camera": {"position": [0, 3, 4], "look_at": [0, 0, 0], "fov": 40}, "ambient": 0.1,
                           "materials": {"m": {"ka": 1, "kd": 0.7, "ks": 0.5, "shininess": 1}},
                           "lights": [{"type": "point", "position": light}],
                           "objects": [{"shape": "plane", "material": "m", "size": [3, 3], "rotate": [30, 0, 0]}]},
                          source="stability")


@case
def light_in_the_surface_plane() -> CaseResult:
    """A light in the surface's plane lights nothing (n·l within LIT_ROUNDINGS units of rounding is 0): the largest
    departure from the ambient term, in both precisions and on both sides."""
    worst = 0.0
    for precision, side in itertools.product(("float32", "float64"), (-1.0, 1.0)):
        image = render(light_in_plane_scene(precision, side)).image
        covered = image.max(axis=2) > 0.0
        worst = max(worst, float(np.abs(image[covered] - 0.1).max()))
    return CaseResult("light in the surface's plane", "a point light exactly in a tilted plane's plane, shininess 1, "
                      "both precisions: every pixel the ambient term within 1e-6 (n·l is rounding alone)",
                      f"largest departure {worst:.1e}", worst <= 1e-6, value=worst, limit=1e-6)


@case
def watertightness() -> CaseResult:
    scene = validate_scene({"objects": [{"shape": "icosphere", "subdivisions": 4}]}, source="stability")
    geometry = build_geometry(scene, vertex_normals=False)
    frame = unit_frame(geometry.vertices)
    accelerator = Accelerator(geometry, frame)
    rng = np.random.default_rng(7)
    edges = np.unique(np.sort(geometry.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    a, b = geometry.vertices[edges[:, 0]], geometry.vertices[edges[:, 1]]
    targets = {"edge midpoints": (a + b) / 2,
               "random edge points": a + rng.uniform(size=(len(a), 1)) * (b - a),
               "vertices": geometry.vertices}
    rates = {}
    for name, points in targets.items():
        # From 3 units outside, along the sphere's normal at the target tilted at random by about 6°:
        # the ray must stop at the target or before it (t ≤ 3); reaching the far side (t ≈ 5) or nothing
        # means it slipped through a crack. (Exactly radial rays through the vertices of an icosphere are
        # a worse case, 2.8 % with robust mode on, 25 % off: symmetric fans of six faces.)
        approach = points / np.linalg.norm(points, axis=1, keepdims=True) + 0.1 * rng.normal(size=points.shape)
        approach /= np.linalg.norm(approach, axis=1, keepdims=True)
        origins = points + 3 * approach
        hits = accelerator.closest_hits(frame.to_unit(origins).astype(np.float32), (-approach).astype(np.float32))
        stopped = (hits.face >= 0) & (hits.t * frame.scale < 3 * (1 + 1e-3))
        rates[name] = float(1 - stopped.mean())
    passed = rates["edge midpoints"] == 0 and rates["random edge points"] == 0 and rates["vertices"] < 0.01
    return CaseResult("watertightness", "rays through every edge midpoint and random edge points of a closed "
                      "mesh all hit; through exact vertices < 1 % miss",
                      ", ".join(f"{k}: {v:.2%} miss" for k, v in rates.items()), passed, value=rates["vertices"],
                      limit=0.01)


# ---------------------------------------------------------------- 9. HDR linearity

@case
def hdr_linearity() -> CaseResult:
    from ..io.image_io import read_image, write_image

    def lit(k: float) -> Scene:
        scene = sphere_scene(32, size=32)
        lights = tuple(l.model_copy(update={"diffuse": tuple(k * v for v in l.diffuse),
                                            "specular": tuple(k * v for v in l.specular)}) for l in scene.lights)  # noqa: E741
        return scene.model_copy(update={"lights": lights, "ambient": tuple(k * v for v in scene.ambient)})

    base = render(lit(1.0)).image.astype(np.float64)
    worst = 0.0
    for k in (1e-6, 1e-3, 1e3, 1e6):
        scaled = render(lit(k)).image.astype(np.float64)
        lit_pixels = base > 1e-3
        worst = max(worst, float(np.abs(scaled[lit_pixels] / (k * base[lit_pixels]) - 1).max()))
    with tempfile.TemporaryDirectory() as folder:
        png = write_image(Path(folder) / "bright.png", render(lit(1e6)).image)
        bright, _ = read_image(png)
    clamps = bool(bright.max() == 1.0 and (bright[base.max(axis=2) > 1e-3] == 1.0).all())
    return CaseResult("HDR linearity", "lights × k (1e-6 … 1e6) scale the linear image by k within 1e-6; "
                      "the PNG clamps at 1 and never wraps", f"worst relative deviation {worst:.1e}",
                      worst < 1e-6 and clamps, value=worst, limit=1e-6)


# ---------------------------------------------------------------- 10. non-finite input

@case
def non_finite_input() -> CaseResult:
    base = {"lights": [{"type": "point", "position": [2, 2, 3]}], "objects": [{"shape": "icosphere"}]}
    bad = {
        "camera.position": {**base, "camera": {"position": [0, float("nan"), 4]}},
        "lights.0.position": {**base, "lights": [{"type": "point", "position": [2, float("inf"), 3]}]},
        "lights.0.diffuse": {**base, "lights": [{"type": "point", "position": [2, 2, 3], "diffuse": float("nan")}]},
        "objects.0.translate": {**base, "objects": [{"shape": "icosphere", "translate": [float("nan"), 0, 0]}]},
        "objects.0.scale": {**base, "objects": [{"shape": "icosphere", "scale": float("inf")}]},
        "ambient": {**base, "ambient": float("nan")},
    }
    named = 0
    for key, data in bad.items():
        try:
            validate_scene(data, source="stability")
        except SceneError as error:  # the location it carries is the key itself, not a mention in the text
            named += dotted(getattr(error.where, "key", ())) == key
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "nan.obj"
        path.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
        try:
            build_geometry(mesh_scene(path))
        except SceneError as error:
            named += getattr(error.where, "key", ()) == ("objects", 0, "path")
    return CaseResult("non-finite input", "NaN or inf in a mesh file, transform, light, camera or ambient is an "
                      "input error naming the field", f"{named} of {len(bad) + 1} refused with the key named",
                      named == len(bad) + 1, value=named, limit=len(bad) + 1, at_least=True)


# ---------------------------------------------------------------- 11. float32 against float64

@case
def float32_against_float64() -> CaseResult:
    """The float64 path against a float64 hand computation; the float32 deviation of the other cases."""
    light = {"type": "directional", "direction": [-math.sin(1.0), 0, -math.cos(1.0)], "diffuse": 0.7, "specular": 0.9}
    scene = head_on_plane(light, {"ka": 0.3, "kd": 0.6, "ks": 0.4, "shininess": 7}, 0.1, precision="float64")
    n_dot_l = math.cos(1.0)
    v_dot_r = math.cos(1.0)  # r = 2(l·n)n − l = (−sin 1, 0, cos 1), v = n = (0, 0, 1)
    expected = 0.1 * 0.3 + 0.7 * 0.6 * n_dot_l + 0.9 * 0.4 * max(v_dot_r, 0) ** 7
    got = render(scene).image[1, 1]
    error64 = float(np.abs(got - expected).max())
    deviations = {name: float32_deviation(make) for name, make in FLOAT32_CASES.items()}
    return CaseResult("float32 against float64", "float64 matches a float64 hand computation to 1e-12; "
                      "the float32 deviation of each case's scene is reported (relative to its largest pixel)",
                      f"float64 error {error64:.1e}; float32: "
                      + ", ".join(f"{k} {v:.0e}" for k, v in deviations.items()),
                      error64 < 1e-12, value=error64, limit=1e-12)


def float32_deviation(make: Callable[[str], Scene]) -> float:
    """max |float32 − float64| / max |float64| of one scene (float32 forced even where the plan would not)."""
    single, double = both_precisions(make("float32"))
    return float(np.abs(single.astype(np.float64) - double).max() / max(np.abs(double).max(), 1e-300))


FLOAT32_CASES: dict[str, Callable[[str], Scene]] = {
    "f = 128": lambda p: sphere_scene(128.0, precision=p),
    "f = 1e4": lambda p: sphere_scene(1e4, precision=p),
    "light 1e-12 off the surface": lambda p: plane_with_light(1e-12, "inverse_square", p),
    "scale 1e6, 4e12 away": lambda p: placed_scene(1e6, 4e12, "local", precision=p),
    "receding quad": lambda p: receding_quad_scene(16.0, "perspective", p),
}


# ---------------------------------------------------------------- 12. perspective against screen space

def receding_quad_scene(ratio: float, interpolation: str, precision: str = "float64") -> Scene:
    """A quad from depth 1 to depth `ratio` in front of the camera; vertex normals (from the file) turn
    from facing a directional light at the near edge to perpendicular at the far edge, so Gouraud's
    diffuse term is an attribute going linearly from 1 to 0 along the depth."""
    folder = scratch_folder()
    near, far = 1.0, ratio
    # The near edge is seen 0.8 below the view axis at depth 1, the far edge 0.5 above it at depth r.
    (folder / f"quad-{ratio:g}.obj").write_text(
        f"v -0.1 {-0.8 * near} -{near}\nv 0.1 {-0.8 * near} -{near}\n"
        f"v 0.1 {0.5 * far} -{far}\nv -0.1 {0.5 * far} -{far}\n"
        "vn 0 0 1\nvn 0 0 1\nvn 1 0 0\nvn 1 0 0\nf 1//1 2//2 3//3\nf 1//1 3//3 4//4\n")
    return validate_scene({
        "render": {"width": 9, "height": 200, "shading": "gouraud", "viewer": "infinite",
                   "interpolation": interpolation, "precision": precision},
        "camera": {"position": [0, 0, 0], "look_at": [0, 0, -1], "fov": 90},
        "ambient": 0,
        "lights": [{"type": "directional", "direction": [0, 0, -1], "diffuse": 1, "specular": 0}],
        "materials": {"m": {"ka": 0, "kd": 1, "ks": 0}},
        "objects": [{"shape": "mesh", "path": f"quad-{ratio:g}.obj", "normals": "file", "material": "m"}],
    }, source="stability", folder=folder)


@functools.cache
def scratch_folder() -> Path:
    """This process's own folder for the suite's mesh files: fresh (mkdtemp, mode 0700), so two runs or two
    users never share or plant files in it; removed when the process exits."""
    folder = Path(tempfile.mkdtemp(prefix="raycast-phong-stability-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    return folder


def interpolation_difference(ratio: float) -> tuple[float, float]:
    """(measured max |perspective − screen| along the receding edge, (√r − 1)/(√r + 1))."""
    perspective = render(receding_quad_scene(ratio, "perspective")).image[:, 4, 0]
    screen = render(receding_quad_scene(ratio, "screen")).image[:, 4, 0]
    covered = (perspective > 0) & (screen > 0)
    measured = float(np.abs(perspective - screen)[covered].max())
    root = math.sqrt(ratio)
    return measured, (root - 1) / (root + 1)


@case
def perspective_against_screen() -> CaseResult:
    rows = [(ratio, *interpolation_difference(ratio)) for ratio in (2.0, 4.0, 16.0)]
    off = max(abs(measured - predicted) for _, measured, predicted in rows)
    agree = off < 0.05
    figure = ", ".join(f"r = {r:g}: {m:.3f} (theory {p:.3f})" for r, m, p in rows)
    return CaseResult("perspective vs screen interpolation", "the difference on a receding edge follows "
                      "(√r − 1)/(√r + 1) of the attribute's range", figure, agree, value=off, limit=0.05)
