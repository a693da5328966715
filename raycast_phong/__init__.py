"""raycast-phong: ray-cast flat, Gouraud and Phong shading on Intel Embree.

    scene = raycast_phong.load_scene("scenes/default.toml")
    result = raycast_phong.render(scene)          # .image (H, W, 3) float32, .timings, .plan
    raycast_phong.write_image("out.png", result.image)
"""

from .image_io import ImageError, read_image, read_layer, write_image
from .plan import build_plan
from .records import RenderPlan, RenderResult
from .render import render, render_file
from .scene import Scene, SceneError, ShadingModel, SpecularModel, default_scene_path, load_scene, validate_scene

__version__ = "0.1.0"
__all__ = ["ImageError", "RenderPlan", "RenderResult", "Scene", "SceneError", "ShadingModel", "SpecularModel",
           "build_plan", "default_scene_path", "load_scene", "read_image", "read_layer", "render", "render_file",
           "validate_scene", "write_image"]
