"""A mesh file made into a scene: one `mesh` object with the file's named materials as [materials.NAME]
tables, a perspective camera framing the model's bounding sphere (a three-quarter view by default; front,
side, top or iso), a key light above and to the left of the camera, and the format's defaults for the rest
(docs/meshes.md).

`--set` overrides apply to that table exactly as to a TOML file's, before the camera is placed, so
`--set render.width=300` or `--set camera.fov=20` still frames the model. The file is read once: its
io.meshes.source.MeshSource is made here and handed on with the scene (load_scene); it keeps the framing read
for the render's.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..codes import OUTPUT_PATH, View
from ..errors import SceneError
from ..io.encoding import DISPLAY, LINEAR
from ..tolerances import MIN_EXTENT, POSITION_LIMIT
from ..values.messages import Location
from .overrides import apply_override

VIEWS = tuple(view.value for view in View)  # the first is the default
AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
DEFAULT_UP = (0.0, 1.0, 0.0)  # most formats state no up axis; +Y is glTF's and most viewers' choice
FILL = 0.9                    # the bounding sphere fills this share of the image's smaller half-extent
# The three-quarter view: 30° round from the front toward the right, 20° above the horizon.
AZIMUTH, ELEVATION = math.radians(30.0), math.radians(20.0)


def mesh_colour(path: str | Path) -> tuple[str, str]:
    """(render.colour, why) for a mesh file rendered directly (docs/meshes.md, "Colour"): LINEAR for a format whose
    specification says its colours are linear (glTF 2.0 §3.9.2: colour textures are sRGB-encoded, factors and
    COLOR_0 linear, lit in linear values and shown through the sRGB curve), else DISPLAY: no other format says,
    and fixed-function GL viewers (MeshLab, the lecture's) show their colours and maps as stored."""
    from ..io.meshes import format_of
    kind = format_of(path)
    if kind.linear:
        return LINEAR, f"the default for a {kind.names[0]} file rendered directly, as {kind.linear} specifies"
    file = f"{Path(path).suffix.lower()} file" if Path(path).suffix else "mesh file"
    return DISPLAY, (f"the default for a {file} rendered directly (the format names no colour space; "
                     "fixed-function GL viewers show its colours as stored)")


# A mesh file's background: dark grey (PNG byte 51 in either colour setting), as viewers show models (f3d,
# MeshLab, Blender), so a surface no light reaches (an open model seen from its unlit side with k_a = 0) shows
# as a black silhouette instead of black on black (docs/meshes.md, "Background").
BACKGROUND = 0.2


def mesh_background(colour: str) -> list[float]:
    """render.background for a mesh file in `colour`: BACKGROUND as written in the PNG (linear: decoded from sRGB,
    so the sRGB curve writes it back as the same byte)."""
    from ..io.textures import srgb_to_linear
    value = float(srgb_to_linear(BACKGROUND)) if colour == LINEAR else BACKGROUND
    return [value, value, value]


def mesh_scene_dict(path: Path, overrides: list[str] | tuple[str, ...] = (), view: str | None = None,
                    up: str | None = None, max_memory: int | None = None, sources: dict | None = None) -> dict:
    """A scene table showing one mesh file: its materials, a framing camera, a key light (docs/meshes.md).
    Reading the file to frame it keeps to `max_memory` bytes (the command's --max-memory) as well as to what
    the machine has. The file's MeshSource is put in `sources` (by io.meshes.source.source_key), if given."""
    from ..io.meshes.content import check_file_content
    from ..io.meshes.size import check_mesh_read
    from ..io.meshes.source import mesh_source, source_key
    where = Location(str(path))
    check_view(view, where)
    source = mesh_source(path, where)
    check_file_content(path, source.format, where)  # an OBJ named .stl is no binary STL of 1702M triangles
    if sources is not None:
        sources[source_key(path)] = source
    check_mesh_read(source, max_memory)  # the framing read comes before render()'s own memory check
    found = source.bounds()  # trimesh: only for mesh files
    return framed_dict(found, path.name, path.stem, mesh_colour(path)[0], overrides, view, up, where)


def check_view(view: str | None, where: Location) -> None:
    if view is not None and view not in VIEWS:
        raise SceneError(f"--view {view!r}; allowed: {', '.join(VIEWS)}", where)


def framed_dict(found, path: str, stem: str, colour: str, overrides: list[str] | tuple[str, ...] = (),
                view: str | None = None, up: str | None = None, where: Location | None = None) -> dict:
    """The scene table showing one mesh (`found`: its io.meshes.read.MeshFile, bounds and materials) at `path`,
    named `stem`: its materials, a framing camera from `view`, a key light, `colour`, then `overrides`. A mesh
    file's (mesh_scene_dict) and a mesh given as arrays' (scene.mesh_arrays) alike."""
    from ..io.meshes.read import FILE_CREASE_ANGLE
    view, where = view or VIEWS[0], where or Location("<mesh>")
    if not found.radius >= MIN_EXTENT:  # every vertex at one point: nothing to frame (or to see)
        centre = [float(x) for x in found.centre]
        raise SceneError(f"every vertex of the model lies within {found.radius:.3g} of {centre}; "
                         f"allowed: a model at least {2 * MIN_EXTENT:g} across", where)
    up_axis = parse_up(up, where) if up is not None else np.asarray(found.up or DEFAULT_UP)
    data: dict = {
        "materials": {m.name: m.as_scene() for m in found.materials},
        # A file without normals is creased at the feature angle (docs/meshes.md, "Normals"): shown by `scene`.
        "objects": [{"name": stem, "shape": "mesh", "path": path,
                     **({} if found.stores_normals else {"crease_angle": FILE_CREASE_ANGLE})}],
        "output": {"path": f"{stem}.png"},
        # before the overrides: --set render.colour and render.background win
        "render": {"colour": colour, "background": mesh_background(colour)},
    }
    data["camera"] = frame_camera(found.centre, found.radius, up_axis, view, (640.0, 480.0), 40.0, False)
    data["lights"] = [key_light(found.centre, data["camera"], up_axis)]
    for assignment in overrides:
        apply_override(data, assignment, source=where)
    # Frame again for the size, field of view and camera type the overrides chose; a key they set wins.
    touched = {tuple(a.split("=", 1)[0].strip().split(".")) for a in overrides}
    output = data.get("output")
    if isinstance(output, dict) and output.get("aovs") and OUTPUT_PATH not in touched:
        output["path"] = f"{stem}.exr"  # layers need EXR, as the format's own default path says
    camera, lights = data.get("camera"), data.get("lights")
    framed_camera = isinstance(camera, dict) and not touched & {("camera",), ("camera", "position")}
    framed_light = isinstance(lights, list) and lights and isinstance(lights[0], dict) and not touched & {
        ("lights",), ("lights", "0"), ("lights", "0", "position")}
    if isinstance(camera, dict) and ("camera",) not in touched:
        placed = frame_camera(found.centre, found.radius, up_axis, view, _render_size(data),
                              _number(camera.get("fov"), 40.0), camera.get("type") == "orthographic")
        camera.update({k: v for k, v in placed.items() if ("camera", k) not in touched})
        if framed_light:
            lights[0]["position"] = key_light(found.centre, camera, up_axis)["position"]
    ours = ([camera["position"]] if framed_camera else []) + ([lights[0]["position"]] if framed_light else [])
    _check_in_reach(found, ours, where)
    return data


def _check_in_reach(found, placed: list, where: Location) -> None:
    """The camera and key light positions the framing placed (not those an override gave) stay within
    POSITION_LIMIT: a model near that limit (or larger than it, or a field of view that puts the camera that far)
    is refused for its own extent, not for a camera.position its user never gave."""
    if max((abs(float(x)) for point in placed for x in point), default=0.0) > POSITION_LIMIT:
        centre = [float(f"{x:.3g}") for x in found.centre]
        raise SceneError(f"a model {2 * found.radius:.3g} across at {centre} is too large or too far out to frame: "
                         f"the camera framing it would stand past ±{POSITION_LIMIT:g}; allowed: a model small and near "
                         f"enough to the origin that its framing camera stays within ±{POSITION_LIMIT:g}", where)


def parse_up(text: str, where: Location) -> np.ndarray:
    """--up: x, y, z with an optional sign (+z, -y)."""
    sign, axis = (-1.0, text[1:]) if text.startswith("-") else (1.0, text.removeprefix("+"))
    if axis.lower() not in AXES:
        raise SceneError(f"--up {text!r}; allowed: x, y, z, -x, -y, -z", where)
    return sign * np.asarray(AXES[axis.lower()])


def _number(value, default: float) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else default


def _render_size(data: dict) -> tuple[float, float]:
    """Width and height the overrides set (the format's defaults otherwise; validation judges bad values)."""
    render = data.get("render") if isinstance(data.get("render"), dict) else {}
    width, height = _number(render.get("width"), 640.0), _number(render.get("height"), 480.0)
    return (width, height) if width > 0 and height > 0 else (640.0, 480.0)


def view_basis(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(front, right) for an up axis: the model's front faces +Z when Y is up, −Y when Z is up (Blender's
    front view), +Z when X is up; right = up × front, so (right, up, front) is right-handed."""
    axis = int(np.argmax(np.abs(up)))
    front = {0: np.array([0.0, 0.0, 1.0]), 1: np.array([0.0, 0.0, 1.0]),
             2: np.array([0.0, -1.0, 0.0]) * np.sign(up[2])}[axis]
    return front, np.cross(up, front)


def frame_camera(centre: np.ndarray, radius: float, up: np.ndarray, view: str, size: tuple[float, float],
                 fov: float, orthographic: bool) -> dict:
    """camera.position, look_at, up (and view_height) so the bounding sphere (centre, radius) fills FILL of
    the image's smaller half-extent, seen from `view`.

    A sphere seen at distance d under half-angle α has sin α = r / d; in a perspective image of vertical
    field of view θ its outline is a circle of radius tan α in the image plane, whose half-height is
    tan(θ/2) (half-width aspect × that). So tan α = FILL · tan β, β the smaller of the two half-angles.
    """
    radius = max(radius, 1e-300)  # a model collapsed to a point is refused by the geometry, not here
    front, right = view_basis(up)
    camera_up = up
    if view == "front":
        direction = front
    elif view == "side":
        direction = right
    elif view == "top":
        direction, camera_up = up, -front  # looking down, the model's front at the bottom of the image
    elif view == "iso":
        direction = (front + right + up) / math.sqrt(3.0)
    else:
        direction = (math.cos(ELEVATION) * (math.cos(AZIMUTH) * front + math.sin(AZIMUTH) * right)
                     + math.sin(ELEVATION) * up)
    aspect = size[0] / size[1]
    half = math.radians(min(max(fov, 1e-3), 179.0)) / 2
    if orthographic:
        distance = 3.0 * radius
        placed = {"view_height": float(2 * radius / FILL * max(1.0, 1.0 / aspect))}
    else:
        limit = min(half, math.atan(aspect * math.tan(half)))
        distance = radius / math.sin(math.atan(FILL * math.tan(limit)))
        placed = {}
    return {"position": [float(x) for x in centre + distance * direction], "look_at": [float(x) for x in centre],
            "up": [float(x) for x in camera_up], **placed}


def key_light(centre: np.ndarray, camera: dict, up: np.ndarray) -> dict:
    """A point light above and to the left of the camera, as far from the model's centre as the camera."""
    try:
        eye = np.asarray(camera["position"], np.float64)
        camera_up = np.asarray(camera.get("up", up), np.float64)
    except (TypeError, ValueError, KeyError):
        return {"type": "point", "position": [float(x) for x in centre + up]}  # validation reports the camera
    to_eye = eye - centre
    distance = float(np.linalg.norm(to_eye)) or 1.0
    to_eye = to_eye / distance
    right = np.cross(-to_eye, camera_up)
    right = right / (np.linalg.norm(right) or 1.0)
    camera_up = np.cross(right, -to_eye)
    toward = to_eye + 0.8 * camera_up - 0.6 * right  # about 40° up and 30° left of the view direction
    return {"type": "point", "position": [float(x) for x in centre + distance * toward / np.linalg.norm(toward)]}
