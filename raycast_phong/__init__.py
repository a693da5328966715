"""raycast-phong: ray-cast flat, Gouraud and Phong shading on Intel Embree.

    scene = raycast_phong.load_scene("scenes/default.toml")
    result = raycast_phong.render(scene)          # .image (H, W, 3) float32, .timings, .plan
    raycast_phong.write_image("out.png", result.image)

The names below load their module on first use (PEP 562), so `import raycast_phong` — and the pytest
plugin, the CLI's --help and `compare` — do not pay for numba, trimesh and Embree (≈ 0.7 s) until
something renders.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING

__version__ = "0.1.0"

_HOMES = {
    "ImageError": "image_io", "read_image": "image_io", "read_layer": "image_io", "write_image": "image_io",
    "build_plan": "plan",
    "RenderPlan": "records", "RenderResult": "records",
    "render": "render", "render_file": "render",
    "Scene": "scene", "SceneError": "scene", "ShadingModel": "scene", "SpecularModel": "scene",
    "default_scene_path": "scene", "load_scene": "scene", "validate_scene": "scene",
}
__all__ = sorted(_HOMES)

if TYPE_CHECKING:
    from .image_io import ImageError, read_image, read_layer, write_image
    from .plan import build_plan
    from .records import RenderPlan, RenderResult
    from .render import render, render_file
    from .scene import (Scene, SceneError, ShadingModel, SpecularModel, default_scene_path, load_scene,
                        validate_scene)


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module 'raycast_phong' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_HOMES[name]}", __name__), name)
    globals()[name] = value  # later lookups skip __getattr__
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_HOMES])


class _Package(types.ModuleType):
    """Importing the submodule raycast_phong.render sets the package's attribute `render` to that module;
    keep the function there instead (the eager `from .render import render` used to overwrite it)."""

    def __setattr__(self, name: str, value) -> None:
        if name in _HOMES and isinstance(value, types.ModuleType):
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
