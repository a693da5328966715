"""Checks on the placed geometry: a scene that would leave float32's range (refused), and one that lies wholly
behind the camera (a warning)."""

from __future__ import annotations

import numpy as np

from ..errors import SceneError
from ..records import Geometry
from ..scene.schema import Scene, brightness_problem
from ..tolerances import MIN_DISTANCE, MIN_EXTENT


def check_float_range(scene: Scene, geometry: Geometry) -> None:
    """Refuse a scene whose placed extent or 1/d² lights would leave float32's range (SceneError), from the
    geometry's bounding box (Geometry.box, computed once per geometry: the lights may change every frame).

    The half-extent must be at least MIN_EXTENT; a 1/d² light's f_att is at most 1/max(d, floor)², d its
    distance to the scene's bounding box and floor tolerances.MIN_DISTANCE × the half-extent, and the lights
    must keep every pixel channel below INTENSITY_LIMIT with that gain (scene.brightness_problem).
    """
    low, high = geometry.box
    extent = float((high - low).max()) / 2  # as intersect.unit_frame measures it
    if extent < MIN_EXTENT:
        raise SceneError(f"the whole scene spans only {2 * extent:.3g} (its largest bounding-box side); allowed: at "
                         f"least {2 * MIN_EXTENT:g}, so the 1/d² floor and Embree's unit frame stay in float32's "
                         "range; raise the objects' scale or size", scene.origin.at("objects"))
    floor = MIN_DISTANCE * extent
    gains = {}
    for k, light in enumerate(scene.lights):
        if light.type == "point" and light.attenuation == "inverse_square":
            position = np.asarray(light.position)
            d = float(np.linalg.norm(np.maximum(np.maximum(low - position, position - high), 0.0)))
            gains[k] = 1.0 / max(d, floor) ** 2
    problem = brightness_problem(scene, gains, why="with 1/d² attenuation up to "
                                 f"{max(gains.values(), default=1.0):.3g} (the light at or near the scene), ")
    if problem:
        raise SceneError(problem[1], scene.origin.at(*problem[0]))


def behind_camera(scene: Scene, geometry: Geometry) -> str | None:
    """A one-line warning if every placed vertex lies behind the camera (or on its plane), else None:
    no ray can hit anything, so the image is only background.

    Asked on every frame of a live view: the geometry's bounding box (Geometry.box, kept with it) answers
    whenever the camera's plane does not cut it, with a margin far above rounding; only a plane through the
    box reads the vertices. (The vertices' product was 7 ms a frame on a 1.11M-triangle scan, and numpy's
    threaded BLAS then kept a core busy spinning for as long again, beside the frame's bands.)"""
    eye = np.asarray(scene.camera.position, np.float64)
    forward = np.asarray(scene.camera.look_at, np.float64) - eye
    plane = float(eye @ forward)
    low, high = geometry.box
    nearest = float(np.minimum(low * forward, high * forward).sum())  # min and max of v·forward over the box
    farthest = float(np.maximum(low * forward, high * forward).sum())
    margin = 1e-9 * (abs(plane) + float(np.maximum(abs(low), abs(high)) @ abs(forward)))
    if nearest > plane + margin:  # the whole box in front
        return None
    # The plane cuts the box: (v - eye)·forward > 0 for some vertex, without a (V, 3) temporary. einsum, not
    # `vertices @ forward`: that is OpenBLAS's threaded gemv, whose worker then spins for tens of ms and takes a core
    # from the frame's tiles that start right after.
    if farthest >= plane - margin and np.einsum("ij,j->i", geometry.vertices, forward).max() > plane:
        return None
    return (f"every object is behind the camera (camera.position {list(scene.camera.position)} looks toward "
            f"look_at {list(scene.camera.look_at)}); the image will be only background")
