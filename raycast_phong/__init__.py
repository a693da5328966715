"""raycast-phong: ray-cast flat, Gouraud and Phong shading on Intel Embree.

    scene = raycast_phong.load_scene("scenes/default.toml")
    result = raycast_phong.render(scene)                  # .image (H, W, 3) float32, .timings, .plan
    raycast_phong.write_image("out.png", result.image, colour=result.colour)  # as render.colour says

The names below load their module on first use (PEP 562), so `import raycast_phong` — and the pytest
plugin, the CLI's --help and `compare` — do not pay for numba, trimesh and Embree (≈ 0.7 s) until
something renders.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"

_HOMES = {
    "read_image": "io.image_io", "read_layer": "io.image_io", "write_image": "io.image_io",
    "ImageError": "errors", "RaycastPhongError": "errors", "SceneError": "errors", "WriteError": "errors",
    "build_plan": "renderer.plan",
    "RenderPlan": "records", "RenderResult": "records",
    "render": "renderer.frame", "render_file": "renderer.frame", "Renderer": "renderer.prepare",
    "ShadingModel": "codes", "SpecularModel": "codes",
    "Scene": "scene.schema", "default_scene_path": "scene.schema", "load_scene": "scene.load",
    "mesh_scene": "scene.mesh_arrays",
    "validate_scene": "scene.schema",
    "show": "tools.notebook",
}
# Spelled out (not sorted(_HOMES)) so type checkers see the public names; tests/project keeps the two equal.
__all__ = ["ImageError", "RaycastPhongError", "RenderPlan", "RenderResult", "Renderer", "Scene", "SceneError",
           "ShadingModel", "SpecularModel", "WriteError", "build_plan", "default_scene_path", "load_scene",
           "mesh_scene", "read_image", "read_layer", "render", "render_file", "show", "validate_scene",
           "write_image"]

if TYPE_CHECKING:  # `X as X`: an explicit re-export (mypy --strict, pyright)
    from .codes import ShadingModel as ShadingModel
    from .codes import SpecularModel as SpecularModel
    from .errors import ImageError as ImageError
    from .errors import RaycastPhongError as RaycastPhongError
    from .errors import SceneError as SceneError
    from .errors import WriteError as WriteError
    from .io.image_io import read_image as read_image
    from .io.image_io import read_layer as read_layer
    from .io.image_io import write_image as write_image
    from .records import RenderPlan as RenderPlan
    from .records import RenderResult as RenderResult
    from .renderer.frame import render as render
    from .renderer.frame import render_file as render_file
    from .renderer.plan import build_plan as build_plan
    from .renderer.prepare import Renderer as Renderer
    from .scene.load import load_scene as load_scene
    from .scene.mesh_arrays import mesh_scene as mesh_scene
    from .scene.schema import Scene as Scene
    from .scene.schema import default_scene_path as default_scene_path
    from .scene.schema import validate_scene as validate_scene
    from .tools.notebook import show as show


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module 'raycast_phong' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_HOMES[name]}", __name__), name)
    globals()[name] = value  # later lookups skip __getattr__
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_HOMES])
