"""Decide, before any ray is cast, which stages and terms this scene needs; leave out the rest.

A left-out term is never evaluated (the shading kernel counts its evaluations, and the tests check
the count is zero) and a left-out stage is never called. `build_plan(scene, optimize=False)` keeps
every optional stage, for tests that compare the two images.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np

from ..codes import GEOMETRY_LAYERS, TERM_LAYERS, Mode, ShadingModel, SpecularModel, StageName, Viewer
from ..geometry.shapes import kind_of, subdivided
from ..records import RenderPlan, Stage
from ..scene.kinds import object_kinds
from ..scene.schema import MAX_SAMPLES, Material, Scene
from .pack import camera_rig


def build_plan(scene: Scene, optimize: bool = True, source: str | None = None) -> RenderPlan:
    """The stages of this scene's render, each kept or left out with its reason; decided per kind of object
    (scene.kinds: objects that differ only in placement), so a million boxes cost one decision. `source` (the
    file the scene was loaded from) words why render.colour is what it is (colour_reason)."""
    kinds = _kinds(scene)
    smooth = [(obj, n) for obj, n in kinds if scene.shading_of(obj) != ShadingModel.FLAT]
    stages, specular = _term_stages(scene, kinds, smooth, optimize)
    stages.append(_view_stage(scene, specular))
    stages += _sampling_stages(scene)
    stages += _shadow_stages(scene, smooth)
    stages += _output_stages(scene)
    stages.append(_precision_stage(scene, specular))
    return RenderPlan(tuple(stages), colour=scene.render.colour, colour_reason=colour_reason(scene, source))


def colour_reason(scene: Scene, source: str | None) -> str:
    """Why the scene renders in its render.colour, and what that means: the default of a mesh file's format
    rendered directly (scene.framing.mesh_colour), a value set (in the file, by --set or --srgb), or the
    scene files' default."""
    colour = scene.render.colour
    meaning = ("maps and colours used as stored, the PNG written as it is" if colour == "display" else
               "8-bit maps decoded from sRGB, lit in linear values, the PNG encoded with the sRGB curve")
    if source is not None:
        from ..scene.load import is_mesh_file
        if is_mesh_file(source):
            from ..scene.framing import mesh_colour
            default, why = mesh_colour(source)
            if colour == default:
                return f"{why}: {meaning}"
    if "colour" in scene.render.model_fields_set:
        return f"render.colour is set: {meaning}"
    return (f"the default for scene files (the lecture's): {meaning}; render.colour = \"linear\" (or --srgb) "
            "for glTF's pipeline")


def _kinds(scene: Scene) -> list[tuple]:
    """(first object, number of objects) of each kind of object in the scene."""
    kinds = object_kinds(scene)
    return list(zip(kinds.firsts(scene.objects), kinds.count.tolist()))


def _any_positive(values) -> bool:
    return any(max(v) > 0 for v in values)


# Stands for the materials a mesh file may bring: every coefficient > 0, so no term is left out for them.
FILE_MATERIALS = Material(ka=1, kd=1, ks=1, ke=1)


def _term_stages(scene: Scene, kinds: list, smooth: list, optimize: bool) -> tuple[list[Stage], bool]:
    """Normals and the model's terms, each kept only where some light and material make it non-zero
    (`optimize=False` keeps the optional ones anyway); and whether the specular term is needed. `kinds` and
    `smooth` (the smooth-shaded ones) are (object, count) pairs."""
    materials, lights, render = [scene.material_of(obj) for obj, _ in kinds], scene.lights, scene.render
    if any(obj.shape == "mesh" and obj.material == "default" for obj, _ in kinds):
        # A mesh file may bring its own materials (read with the geometry, after this plan): keep every term.
        materials.append(FILE_MATERIALS)
    stages = []

    def add(name: StageName, needed: bool, why_kept: str, why_left_out: str) -> None:
        kept = needed or not optimize
        reason = why_kept if needed else (why_left_out if kept is False else f"kept for comparison: {why_left_out}")
        stages.append(Stage(name, kept, reason))

    add(StageName.VERTEX_NORMALS, bool(smooth),
        f"{sum(n for _, n in smooth)} object(s) with Gouraud or Phong shading",
        "every object is flat-shaded: face normals only")
    creased = sum(n for obj, n in smooth if obj.crease_angle < 180)
    # A mesh object leaving crease_angle and normals unset creases a file without normals
    # (geometry.templates.file_crease_angle).
    maybe = sum(n for obj, n in smooth if obj.shape == "mesh" and obj.normals is None
                and "crease_angle" not in obj.model_fields_set)
    if maybe:
        from ..io.materials import FILE_CREASE_ANGLE
    add(StageName.CREASE_SPLIT, bool(creased or maybe),
        "; ".join(([f"{creased} smooth object(s) with crease_angle < 180°"] if creased else [])
                  + ([f"{maybe} mesh object(s) creased at {FILE_CREASE_ANGLE:g}° if the file stores no "
                      "normals (set crease_angle to choose)"] if maybe else [])),
        "no smooth object has a crease angle below 180°")
    own = [m for m in materials if m is not FILE_MATERIALS]
    add(StageName.EMISSION, _any_positive(m.ke for m in materials),
        "some material has k_e > 0" if _any_positive(m.ke for m in own)
        else "a mesh file's own materials may have k_e > 0 (read with the geometry)", "every material's k_e is 0")
    add(StageName.SCENE_AMBIENT, max(scene.ambient) > 0 and _any_positive(m.ka for m in materials),
        "I_a and some k_a are > 0", "I_a is 0 or every k_a is 0")
    add(StageName.LIGHT_AMBIENT,
        _any_positive(light.ambient for light in lights) and _any_positive(m.ka for m in materials),
        "some light has its own ambient and some k_a > 0", "no light has its own ambient (or every k_a is 0)")
    add(StageName.DIFFUSE, _any_positive(light.diffuse for light in lights) and _any_positive(m.kd for m in materials),
        "some light's I_d and some k_d are > 0", "no light has I_d > 0 with a material whose k_d > 0")
    specular = _any_positive(light.specular for light in lights) and _any_positive(m.ks for m in materials)
    formula = "max(v·r, 0)^f" if render.specular == SpecularModel.PHONG else "max(n·h, 0)^f, h = normalize(l + v)"
    add(StageName.SPECULAR, specular, f"{render.specular.value}: {formula}",
        "every material's k_s or every light's I_s is 0")
    attenuating = [light for light in lights if light.type == "point" and light.attenuation != "none"]
    add(StageName.ATTENUATION, bool(attenuating), f"{len(attenuating)} point light(s) attenuate",
        "no point light attenuates: f_att = 1")
    return stages, specular


def _view_stage(scene: Scene, specular: bool) -> Stage:
    """v per point only for a local viewer and a perspective camera, and only if there is a highlight."""
    render = scene.render
    per_point = specular and render.viewer == Viewer.LOCAL and scene.camera.type == "perspective"
    if per_point:
        why = "local viewer, perspective camera: v = normalize(eye − p) per point"
    elif not specular:
        why = "no specular term, so no view vector"
    elif render.viewer == Viewer.INFINITE:
        why = "infinite viewer: one view vector, −forward, for the whole image"
    else:
        why = "orthographic camera: the eye is at infinity, one view vector −forward"
    return Stage(StageName.VIEW_VECTOR_PER_POINT, per_point, why)


def _sampling_stages(scene: Scene) -> list[Stage]:
    """Supersampling, screen-space interpolation and two-sided shading, as the render keys ask."""
    render = scene.render
    screen = render.interpolation == "screen"
    return [
        Stage(StageName.SUPERSAMPLING, render.samples > 1,
              f"{render.samples}×{render.samples} rays per pixel, averaged" if render.samples > 1
              else "samples = 1: one ray through each pixel centre, no averaging loop"),
        Stage(StageName.SCREEN_INTERPOLATION, screen,
              "interpolation = screen: weights linear in the image plane" if screen
              else "perspective-correct weights straight from Embree"),
        Stage(StageName.TWO_SIDED, render.two_sided,
              "back-facing hits are shaded with the normal flipped toward the viewer" if render.two_sided
              else "two_sided = false: back faces shaded with their own normal"),
    ]


def _shadow_stages(scene: Scene, smooth: list) -> list[Stage]:
    """Global mode's shadow rays (only with lights), and Hanika's terminator fix (only on smooth faces)."""
    render, lights = scene.render, scene.lights
    global_mode = render.mode == Mode.GLOBAL
    if global_mode and not lights:
        shadow_reason = "mode = global but the scene has no lights: nothing to shadow"
    elif global_mode:
        shadow_reason = f"mode = global: an occlusion query per hit and light ({len(lights)} light(s))"
    else:
        shadow_reason = "mode = local: the local model knows no other surface"
    shadows = global_mode and bool(lights)
    hanika = shadows and bool(smooth) and render.terminator == "hanika"
    if hanika:
        terminator_reason = "Gouraud/Phong faces: shadow rays start on the smooth surface (Hanika 2021)"
    elif not shadows:
        terminator_reason = "no shadow rays"
    elif not smooth:
        terminator_reason = "every object is flat-shaded: the facets are the surface"
    else:
        terminator_reason = 'terminator = "none": shadow rays start at the hit point'
    return [Stage(StageName.SHADOW_RAYS, shadows, shadow_reason),
            Stage(StageName.TERMINATOR_FIX, hanika, terminator_reason)]


def _output_stages(scene: Scene) -> list[Stage]:
    """The layers asked for, and the shading models in use."""
    geometry_aovs = sorted(set(GEOMETRY_LAYERS) & set(scene.output.aovs))
    term_aovs = sorted(set(TERM_LAYERS) & set(scene.output.aovs))
    models = {scene.shading_of(obj) for obj, _ in _kinds(scene)}
    return [
        Stage(StageName.AOV_GEOMETRY, bool(geometry_aovs),
              f"layers {', '.join(geometry_aovs)}" if geometry_aovs else "no depth/normal/face layer asked for"),
        Stage(StageName.AOV_TERMS, bool(term_aovs),
              f"layers {', '.join(term_aovs)}" if term_aovs else "no per-term layer asked for"),
        Stage(StageName.SHADING_MODELS, True, ", ".join(sorted(m.value for m in models))),
    ]


def _precision_stage(scene: Scene, specular: bool) -> Stage:
    """float64 shading when asked, or when a highlight is too stiff for float32 (F32_SHININESS_LIMIT)."""
    materials = [scene.material_of(obj) for obj, _ in _kinds(scene)]
    stiff = sorted({m.shininess for m in materials if m.shininess > F32_SHININESS_LIMIT}) if specular else []
    if scene.render.precision == "float64":
        reason = "precision = float64"
    elif stiff:
        reason = (f"shininess {stiff[-1]:g} > {F32_SHININESS_LIMIT:g}: a float32 cosine (relative "
                  "error 2^-24) would move such a highlight by more than half an 8-bit step, "
                  "so this scene is shaded in float64")
    else:
        reason = "precision = float32"
    return Stage(StageName.FLOAT64_SHADING, scene.render.precision == "float64" or bool(stiff), reason)


def surface_maps(geometry, colour: str) -> list[Stage]:
    """Whether shading samples colour maps and interpolates vertex colours: work only some scenes need. The
    reason says how the maps were decoded for render.colour `colour` (docs/meshes.md, Textures)."""
    maps = [texture.name for texture in geometry.textures]
    textured = bool(maps) and len(geometry.corner_uv) > 0
    shown = ", ".join(maps[:3]) + (f" and {len(maps) - 3} more" if len(maps) > 3 else "")
    how = "used as stored" if colour == "display" else "8-bit ones decoded from sRGB to linear values"
    return [Stage(StageName.TEXTURES, textured,
                  f"{len(maps)} colour map{'s' if len(maps) != 1 else ''} ({shown}), {how} (colour = {colour})"
                  if textured else "no material has a colour map"),
            Stage(StageName.VERTEX_COLOURS, len(geometry.corner_colour) > 0,
                  "vertex colours multiply k_a and k_d at each face corner" if len(geometry.corner_colour)
                  else "no face has vertex colours")]


# Above this shininess one float32 rounding of the cosine x (relative 2^-24) changes x^f by about
# f · 2^-24 > 1/512 relative, half an 8-bit step: float32 no longer represents the highlight.
F32_SHININESS_LIMIT = 2.0 ** 24 / 512


class ObjectFigures:
    """What diagnose measures on a geometry per object, whatever the scene's lights, camera and materials:
    each object's bounding centre and radius, and the median spread of its faces' corner normals. Computed
    when first asked; `kept` (a FrameCache's reuse.Derived of this geometry) keeps them for the next frames
    (the same numbers, computed the same way, as without it)."""

    def __init__(self, geometry, objects: int, kept=None):
        self.geometry, self.objects, self.kept = geometry, objects, kept

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) centre of each object's bounding box and (N,) the largest distance of its vertices from it,
        over the vertices its faces use (objects own disjoint vertex ranges)."""
        if self.kept is not None:
            return self.kept.get("object bounds", ("vertices", "faces", "face_object"), self._bounds)
        return self._bounds()

    def _bounds(self) -> tuple[np.ndarray, np.ndarray]:
        geometry = self.geometry
        vertex_object = np.full(len(geometry.vertices), -1, np.int64)
        vertex_object[geometry.faces] = geometry.face_object[:, None]
        used = np.flatnonzero(vertex_object >= 0)
        used = used[np.argsort(vertex_object[used], kind="stable")]
        owner, points = vertex_object[used], geometry.vertices[used]
        present, first = np.unique(owner, return_index=True)
        centre = np.zeros((self.objects, 3))
        centre[present] = (np.minimum.reduceat(points, first) + np.maximum.reduceat(points, first)) / 2
        radius = np.zeros(self.objects)
        radius[present] = np.maximum.reduceat(np.linalg.norm(points - centre[owner], axis=1), first)
        return centre, radius

    def spread(self, wanted: np.ndarray) -> np.ndarray:
        """(N,) the median over each `wanted` object's faces of their corner normals' largest angle (radians;
        0 elsewhere). Kept, every object is measured the first time (the median of one object's faces does not
        depend on which other objects are measured with it), so that another choice of objects is free."""
        if self.kept is not None:
            every = self.kept.get("object normal spread", ("corner_normals", "face_object"),
                                  lambda: self._spread(np.ones(self.objects, bool)))
            return np.where(wanted, every, 0.0)
        return self._spread(wanted)

    def _spread(self, wanted: np.ndarray) -> np.ndarray:
        geometry = self.geometry
        picked = np.flatnonzero(wanted[geometry.face_object])
        return group_median(face_normal_spread(geometry.corner_normals[picked]), geometry.face_object[picked],
                            self.objects)


def diagnose(plan: RenderPlan, scene: Scene, geometry, figures: ObjectFigures | None = None) -> RenderPlan:
    """The plan with what the geometry tells: repaired windings, and highlights the render will miss.

    - Gouraud samples the model only at vertices: when neighbouring vertex normals are further apart
      than the highlight is wide (about 1/√f radians), the highlight is lost or smeared.
    - A highlight narrower than a pixel may fall between the pixel centres: supersample.

    A Gouraud object whose own `shading` key chose Gouraud (the default figure's middle sphere) is shown so on
    purpose: its finding is a note, which teaches the same advice, not a warning; Gouraud from render.shading
    (or --shading) is a warning. Every figure is computed for all objects at once (grouped by object,
    O(faces + objects)), and objects with the same finding share one line (aggregate_warnings): 40,000 spheres
    give one line, not 40,000. `figures` (ObjectFigures of this geometry, kept by a FrameCache) holds what was
    measured on it before.
    """
    figures = figures or ObjectFigures(geometry, len(scene.objects))
    stages = list(plan.stages)
    stages.append(Stage(StageName.WINDING_REPAIR, bool(geometry.notes),
                        "; ".join(aggregate_notes(geometry.notes)) if geometry.notes
                        else "no mesh file needed a winding repair"))
    stages += surface_maps(geometry, plan.colour)
    found: list[tuple[tuple, int, float]] = []  # (what the warning says, object, its measured figure)
    if plan.keeps(StageName.SPECULAR):
        found = [*gouraud_findings(scene, geometry, figures), *subpixel_findings(scene, geometry, figures)]
    from ..geometry.checks import behind_camera  # geometry loads trimesh: only once a render has geometry
    behind = behind_camera(scene, geometry.vertices)
    chosen = [item for item in found if item[0][0] == "gouraud" and item[0][-1]]
    warned = [item for item in found if not (item[0][0] == "gouraud" and item[0][-1])]
    return dataclasses.replace(plan, stages=tuple(stages), notes=(*aggregate_warnings(chosen), *geometry.file_notes),
                               warnings=(*([behind] if behind else []), *aggregate_warnings(warned)))


def _candidates(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Objects whose highlight has a width (k_s > 0, 0 < f < ∞), and every object's f, (N,)."""
    materials = [scene.material_of(obj) for obj, _ in _kinds(scene)]
    shininess = np.array([m.shininess for m in materials], np.float64)
    specular = np.array([max(m.ks) > 0 for m in materials], bool)
    kind = object_kinds(scene).kind
    return (specular & (shininess > 0) & np.isfinite(shininess))[kind], shininess[kind]


def _per_object(scene: Scene, test) -> np.ndarray:
    """(N,) bool: test(object) of every object, evaluated once per kind."""
    return np.array([bool(test(obj)) for obj, _ in _kinds(scene)], bool)[object_kinds(scene).kind]


def gouraud_findings(scene: Scene, geometry, figures: ObjectFigures | None = None):
    """Gouraud objects whose vertex normals are further apart than their highlight is wide; the finding ends
    with whether the object's own `shading` key chose Gouraud."""
    wanted, shininess = _candidates(scene)
    gouraud = _per_object(scene, lambda obj: scene.shading_of(obj) == ShadingModel.GOURAUD)
    wanted &= gouraud
    if not wanted.any() or not len(geometry.corner_normals):
        return
    spacing = (figures or ObjectFigures(geometry, len(scene.objects))).spread(wanted)
    highlight = 1 / np.sqrt(np.where(wanted, shininess, 1.0))  # radians where S falls to ≈ e^-1/2
    for index in np.flatnonzero(wanted & (spacing > highlight)):
        obj, f = scene.objects[index], shininess[index]
        more = math.ceil(math.log2(spacing[index] / highlight[index]))
        kind = kind_of(obj)
        how = kind.finer(obj, more) if kind is not None else subdivided(more)
        chosen = obj.shading == ShadingModel.GOURAUD
        yield ("gouraud", f, math.degrees(highlight[index]), how, chosen), int(index), math.degrees(spacing[index])


def own_shading(scene: Scene) -> tuple[str, int, bool] | None:
    """The objects whose own `shading` key differs from render.shading, which therefore changes nothing for them:
    (their key paths as aggregate_warnings words them, how many, whether no object follows render.shading at
    all), or None if render.shading is every object's model. One pass per kind of object."""
    model = scene.render.shading
    differ = _per_object(scene, lambda obj: obj.shading is not None and obj.shading != model)
    if not differ.any():
        return None
    follows = _per_object(scene, lambda obj: obj.shading is None)
    indices = np.flatnonzero(differ).tolist()
    return _objects(indices), len(indices), not follows.any()


def subpixel_findings(scene: Scene, geometry, figures: ObjectFigures | None = None):
    """Curved objects whose highlight is narrower than a pixel (with one sample per pixel)."""
    if scene.render.samples > 1:
        return
    wanted, shininess = _candidates(scene)
    wanted &= _per_object(scene, lambda obj: obj.shape == "mesh" or kind_of(obj).curved)
    if not wanted.any():
        return
    centre, radius = (figures or ObjectFigures(geometry, len(scene.objects))).bounds()
    highlight = 1 / np.sqrt(np.where(wanted, shininess, 1.0))
    width_px = highlight_width_pixels(scene, centre, radius, highlight)
    for index in np.flatnonzero(wanted & (width_px < 1)):
        yield ("subpixel", shininess[index]), int(index), float(width_px[index])


def face_normal_spread(corner_normals: np.ndarray) -> np.ndarray:
    """Largest angle between two of each face's corner normals (F,), radians."""
    pairs = [(0, 1), (1, 2), (2, 0)]
    cosines = np.stack([np.einsum("ij,ij->i", corner_normals[:, a], corner_normals[:, b]) for a, b in pairs])
    return np.arccos(np.clip(cosines.min(axis=0), -1, 1))


def group_median(values: np.ndarray, groups: np.ndarray, count: int) -> np.ndarray:
    """Median of `values` within each group 0..count-1 (N,) as np.median takes it; 0 for an empty group."""
    order = np.lexsort((values, groups))
    values, groups = values[order], groups[order]
    sizes = np.bincount(groups, minlength=count)
    first = np.cumsum(sizes) - sizes
    median = np.zeros(count)
    full = sizes > 0
    low, high = first[full] + (sizes[full] - 1) // 2, first[full] + sizes[full] // 2
    median[full] = (values[low] + values[high]) / 2  # the middle one, or the mean of the middle two
    return median


def highlight_width_pixels(scene: Scene, centre: np.ndarray, radius: np.ndarray, highlight: np.ndarray) -> np.ndarray:
    """Rough width on screen (N,) of a highlight `highlight` radians wide on curved objects: each object's
    bounding radius R stands in for its radius of curvature, so the highlight spans R·highlight."""
    rig = camera_rig(scene)
    # The image plane's half-height is in world units for an orthographic camera, per unit distance otherwise.
    distance = np.ones(len(centre)) if rig.orthographic else np.linalg.norm(centre - rig.eye, axis=1)
    pixel = 2 * rig.half_height * distance / scene.render.height
    with np.errstate(divide="ignore", invalid="ignore"):  # an object at the eye: no width to speak of
        return np.where(pixel > 0, radius * highlight / np.where(pixel > 0, pixel, 1.0), np.inf)


SHOWN_OBJECTS = 3  # object numbers listed in an aggregated warning before "…"


def aggregate_warnings(found: list[tuple[tuple, int, float]]) -> tuple[str, ...]:
    """One line per distinct warning: objects with the same finding share it, with the range of their
    figures and the advice for the worst of them; a lone object keeps the key path `objects.N`."""
    groups: dict[tuple, list[tuple[int, float]]] = {}
    # In object order, an object's Gouraud finding before its sub-pixel one: lines come in the order of the
    # first object each names.
    for what, index, figure in sorted(found, key=lambda item: (item[1], item[0][0] != "gouraud")):
        groups.setdefault(what, []).append((index, figure))
    lines = []
    for what, members in groups.items():
        indices, figures = [m[0] for m in members], [m[1] for m in members]
        who = _objects(indices)
        if what[0] == "gouraud":
            _, f, highlight, how, chosen = what
            spread = _span(min(figures), max(figures), ".1f")
            if chosen:  # the scene asked for this object's Gouraud: say what it shows, and how to resolve it
                lines.append(f"{who} (gouraud, its own `shading`): vertex normals {spread}° apart are wider than the "
                             f"f = {f:g} highlight (about {highlight:.1f}°), so Gouraud shading misses or smears it, "
                             f"as this object shows; {how}, or Phong shading, would resolve it")
                continue
            lines.append(f"{who} (gouraud): vertex normals are {spread}° apart but the f = {f:g} highlight is about "
                         f"{highlight:.1f}° wide, so Gouraud shading will miss or smear it; use {how}, or Phong "
                         "shading")
        else:
            f, narrowest = what[1], min(figures)
            wanted = math.ceil(2 / narrowest)  # two samples across the narrowest highlight
            advice = (f"use render.samples = {wanted} or more" if wanted <= MAX_SAMPLES else
                      f"use render.samples = {MAX_SAMPLES} (the most allowed) and a larger image "
                      f"(about {wanted / MAX_SAMPLES:.0f}× the width and height)")
            lines.append(f"{who}: the f = {f:g} highlight is about {_span(narrowest, max(figures), '.2f')} pixel "
                         f"wide and may fall between pixel centres; {advice}")
    return tuple(lines)


def aggregate_notes(notes: tuple[str, ...]) -> list[str]:
    """Geometry notes ("objects.N: what happened") with the same text after the object share one entry."""
    groups: dict[str, list[int]] = {}
    for note in notes:
        match = re.fullmatch(r"objects\.(\d+): (.*)", note)
        if match is None:
            groups.setdefault(note, [])
        else:
            groups.setdefault(match[2], []).append(int(match[1]))
    return [f"{_objects(indices)}: {text}" if indices else text for text, indices in groups.items()]


def _objects(indices: list[int]) -> str:
    """'objects.3' for one object; 'objects 3, 7, 12 … (40,000 in all)' for several."""
    if len(indices) == 1:
        return f"objects.{indices[0]}"
    shown = ", ".join(str(i) for i in indices[:SHOWN_OBJECTS])
    return f"objects {shown}{' …' if len(indices) > SHOWN_OBJECTS else ''} ({len(indices):,} in all)"


def _span(low: float, high: float, spec: str) -> str:
    """'0.25' or '0.05–0.31': one figure, or the range when the objects differ."""
    a, b = format(low, spec), format(high, spec)
    return a if a == b else f"{a}–{b}"
