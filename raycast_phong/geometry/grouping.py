"""Which objects share one build: objects of one shape and parameters (and normal rule) form a group whose
template is made once and placed for all of them; a mesh file is a group of its own.
"""

from __future__ import annotations

import numpy as np

from ..scene.alike import alike
from ..scene.objects import OWN_KEYS
from ..scene.schema import Object, Scene
from ..shapes import from_file
from .memo import mesh_stamp


def object_groups(scene: Scene) -> list[np.ndarray]:
    """The objects (ascending indices) of each group of objects sharing one build (group_key), groups in the
    order of their first object. Decided once per set of alike objects (scene/alike.py), then spread to the
    objects."""
    sets = alike(scene)
    numbers: dict[tuple, int] = {}
    set_group = np.array([numbers.setdefault(group_key(scene.objects[i], i), len(numbers))
                          for i in sets.first.tolist()], np.int64)
    return sets.grouped(set_group)


def group_key(obj: Object, index: int) -> tuple:
    """What makes two objects' meshes (and normals) the same before placement: equal keys share one build.
    A mesh file is never shared (its reading notes and materials belong to its object)."""
    if from_file(obj):
        return (obj.shape, index)
    return (obj.shape, *(getattr(obj, key) for key in OWN_KEYS[obj.shape]), obj.normals, obj.crease_angle)


def template_key(scene: Scene, index: int, wants_exact: bool, sources: dict | None = None) -> tuple:
    """What group_template reads of the group whose first object is scene.objects[index]: a shape's keys; a
    mesh file's object, its file as it is now (its version and its side files', MeshSource.identity) and the
    object's number and the scene's origin, which its notes name."""
    first = scene.objects[index]
    if not from_file(first):
        return ("shape", *group_key(first, index), wants_exact)
    return (first.shape, index, scene.origin, mesh_stamp(scene.resolve(first.path), sources), first.normals,
            first.crease_angle, "crease_angle" in first.model_fields_set, wants_exact)
