"""Decide, before any ray is cast, which stages and terms this scene needs; leave out the rest.

A left-out term is never evaluated (the shading kernel counts its evaluations, and the tests check
the count is zero) and a left-out stage is never called. `build_plan(scene, optimize=False)` keeps
every optional stage, for tests that compare the two images.
"""

from __future__ import annotations

from ..codes import GEOMETRY_LAYERS, TERM_LAYERS, Mode, ShadingModel, SpecularModel, StageName, Viewer
from ..records import RenderPlan, Stage
from ..scene.alike import alike
from ..scene.schema import Material, Scene
from ..shapes import from_file


def build_plan(scene: Scene, optimize: bool = True) -> RenderPlan:
    """The stages of this scene's render, each kept or left out with its reason; decided per set of alike
    objects (scene/alike.py: objects that differ only in placement), so a million boxes cost one decision. The
    scene's origin (the file it was loaded from) words why render.colour is what it is (colour_reason)."""
    sets = distinct(scene)
    smooth = [(obj, n) for obj, n in sets if scene.shading_of(obj) != ShadingModel.FLAT]
    stages, specular = _term_stages(scene, sets, smooth, optimize)
    stages.append(_view_stage(scene, specular))
    stages += _sampling_stages(scene)
    stages += _shadow_stages(scene, smooth)
    stages += _output_stages(scene)
    stages.append(_precision_stage(scene, specular))
    return RenderPlan(tuple(stages), colour=scene.render.colour, colour_reason=colour_reason(scene))


def colour_reason(scene: Scene) -> str:
    """Why the scene renders in its render.colour, and what that means: the default of a mesh file's format
    rendered directly (scene.framing.mesh_colour), a value set (in the file, by --set or --srgb), or the
    scene files' default."""
    colour = scene.render.colour
    meaning = ("maps and colours used as stored, the PNG written as it is" if colour == "display" else
               "8-bit maps decoded from sRGB, lit in linear values, the PNG encoded with the sRGB curve")
    source = scene.origin.file  # the file the scene came from: a mesh file rendered directly, or a scene file
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


def distinct(scene: Scene) -> list[tuple]:
    """(first object, number of objects) of each set of alike objects in the scene."""
    sets = alike(scene)
    return list(zip(sets.firsts(scene.objects), sets.count.tolist()))


def _any_positive(values) -> bool:
    return any(max(v) > 0 for v in values)


# Stands for the materials a mesh file may bring: every coefficient > 0, so no term is left out for them.
FILE_MATERIALS = Material(ka=1, kd=1, ks=1, ke=1)


def _term_stages(scene: Scene, sets: list, smooth: list, optimize: bool) -> tuple[list[Stage], bool]:
    """Normals and the model's terms, each kept only where some light and material make it non-zero
    (`optimize=False` keeps the optional ones anyway); and whether the specular term is needed. `sets` and
    `smooth` (the smooth-shaded ones) are (object, count) pairs."""
    materials, lights, render = [scene.material_of(obj) for obj, _ in sets], scene.lights, scene.render
    if any(from_file(obj) and obj.material == "default" for obj, _ in sets):
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
    maybe = sum(n for obj, n in smooth if from_file(obj) and obj.normals is None
                and "crease_angle" not in obj.model_fields_set)
    if maybe:
        from ..io.meshes.materials import FILE_CREASE_ANGLE
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
    models = {scene.shading_of(obj) for obj, _ in distinct(scene)}
    return [
        Stage(StageName.AOV_GEOMETRY, bool(geometry_aovs),
              f"layers {', '.join(geometry_aovs)}" if geometry_aovs else "no depth/normal/face layer asked for"),
        Stage(StageName.AOV_TERMS, bool(term_aovs),
              f"layers {', '.join(term_aovs)}" if term_aovs else "no per-term layer asked for"),
        Stage(StageName.SHADING_MODELS, True, ", ".join(sorted(m.value for m in models))),
    ]


def _precision_stage(scene: Scene, specular: bool) -> Stage:
    """float64 shading when asked, or when a highlight is too stiff for float32 (F32_SHININESS_LIMIT)."""
    materials = [scene.material_of(obj) for obj, _ in distinct(scene)]
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

# Above this shininess one float32 rounding of the cosine x (relative 2^-24) changes x^f by about
# f · 2^-24 > 1/512 relative, half an 8-bit step: float32 no longer represents the highlight.
F32_SHININESS_LIMIT = 2.0 ** 24 / 512
