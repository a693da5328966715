"""What the built geometry tells the plan (diagnose): repaired windings, whether colour maps and vertex colours
are used, highlights the render will miss (Gouraud vertex normals too far apart, a highlight narrower than a
pixel), a scene wholly behind the camera; one line per finding, shared by the objects that have it.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np

from ..codes import ALPHA_CUTOFF, BLENDED_ALPHA, ShadingModel, StageName
from ..geometry.checks import behind_camera
from ..geometry.file_materials import first_file_row
from ..geometry.kernels import object_bounds
from ..records import RenderPlan, Stage
from ..scene.alike import alike
from ..scene.schema import MAX_SAMPLES, Scene
from ..shapes import kind_of
from .pack import camera_rig
from .plan import distinct


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
        centre, radius = np.zeros((self.objects, 3)), np.zeros(self.objects)
        object_bounds(geometry.vertices, geometry.faces, geometry.face_object, centre, radius)  # 1M faces: ~5 ms
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
        found = [*gouraud_findings(scene, geometry, figures), *subpixel_findings(scene, figures)]
    behind = behind_camera(scene, geometry)
    chosen = [item for item in found if item[0][0] == "gouraud" and item[0][-1]]
    warned = [item for item in found if not (item[0][0] == "gouraud" and item[0][-1])]
    dither = blend_dither(scene, geometry)
    return dataclasses.replace(plan, stages=tuple(stages), notes=(*aggregate_warnings(chosen), *geometry.file_notes),
                               warnings=(*([behind] if behind else []), *aggregate_warnings(warned),
                                         *([dither] if dither else [])))


BLEND_SAMPLES = 4  # samples a pixel at which BLEND's coverage reads as a blend (±0.25 of alpha at most, 1σ)


def blend_dither(scene: Scene, geometry) -> str | None:
    """A warning when a face's material is alphaMode BLEND (drawn as coverage: a sample sees it with probability
    alpha) and a pixel has fewer than BLEND_SAMPLES² samples: the surface then shows as a dither."""
    rows = geometry.file_materials
    if scene.render.samples >= BLEND_SAMPLES or not len(rows) or not (rows[:, ALPHA_CUTOFF] == BLENDED_ALPHA).any():
        return None
    used = np.unique(geometry.face_material) - first_file_row(scene)
    used = used[(used >= 0) & (used < len(rows))]
    if not (rows[used, ALPHA_CUTOFF] == BLENDED_ALPHA).any():
        return None
    return (f"a mesh file's alphaMode BLEND is drawn as coverage (a sample sees the surface with probability alpha): "
            f"at render.samples = {scene.render.samples} it shows as a dither; use render.samples = {BLEND_SAMPLES} "
            "or more")


def _candidates(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Objects whose highlight has a width (k_s > 0, 0 < f < ∞), and every object's f, (N,)."""
    materials = [scene.material_of(obj) for obj, _ in distinct(scene)]
    shininess = np.array([m.shininess for m in materials], np.float64)
    specular = np.array([max(m.ks) > 0 for m in materials], bool)
    of = alike(scene).of
    return (specular & (shininess > 0) & np.isfinite(shininess))[of], shininess[of]


def per_object(scene: Scene, test) -> np.ndarray:
    """(N,) bool: test(object) of every object, evaluated once per set of alike objects."""
    return np.array([bool(test(obj)) for obj, _ in distinct(scene)], bool)[alike(scene).of]


def gouraud_findings(scene: Scene, geometry, figures: ObjectFigures):
    """Gouraud objects whose vertex normals are further apart than their highlight is wide; the finding ends
    with whether the object's own `shading` key chose Gouraud."""
    wanted, shininess = _candidates(scene)
    wanted &= per_object(scene, lambda obj: scene.shading_of(obj) == ShadingModel.GOURAUD)
    if not wanted.any() or not len(geometry.corner_normals):
        return
    spacing = figures.spread(wanted)
    highlight = 1 / np.sqrt(np.where(wanted, shininess, 1.0))  # radians where S falls to ≈ e^-1/2
    for index in np.flatnonzero(wanted & (spacing > highlight)):
        obj, f = scene.objects[index], shininess[index]
        more = math.ceil(math.log2(spacing[index] / highlight[index]))
        how = kind_of(obj).finer(obj, more)
        chosen = obj.shading == ShadingModel.GOURAUD
        yield ("gouraud", f, math.degrees(highlight[index]), how, chosen), int(index), math.degrees(spacing[index])


def subpixel_findings(scene: Scene, figures: ObjectFigures):
    """Curved objects whose highlight is narrower than a pixel (with one sample per pixel)."""
    if scene.render.samples > 1:
        return
    wanted, shininess = _candidates(scene)
    wanted &= per_object(scene, lambda obj: kind_of(obj).curved)
    if not wanted.any():
        return
    centre, radius = figures.bounds()
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
        who = named_objects(indices)
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
    return [f"{named_objects(indices)}: {text}" if indices else text for text, indices in groups.items()]


def named_objects(indices: list[int]) -> str:
    """'objects.3' for one object; 'objects 3, 7, 12 … (40,000 in all)' for several."""
    if len(indices) == 1:
        return f"objects.{indices[0]}"
    shown = ", ".join(str(i) for i in indices[:SHOWN_OBJECTS])
    return f"objects {shown}{' …' if len(indices) > SHOWN_OBJECTS else ''} ({len(indices):,} in all)"


def _span(low: float, high: float, spec: str) -> str:
    """'0.25' or '0.05–0.31': one figure, or the range when the objects differ."""
    a, b = format(low, spec), format(high, spec)
    return a if a == b else f"{a}–{b}"


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
