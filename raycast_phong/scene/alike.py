"""A scene's objects in sets of alike objects: objects equal in every key but their name and placement.

Whatever the plan, the memory estimate and the geometry decide from an object's shape, material and shading
they decide once per set and spread to the objects with `of` (a million boxes of one material are one set:
one decision, not a million). Mesh objects are each a set of their own, as their file's materials, notes and
crease default belong to the object. Computed once per Scene (in two C-level passes over the objects) and
kept while the Scene lives. (A shape's kind, shapes/, is another thing: what an object is built as.)
"""

from __future__ import annotations

import gc
import operator
import weakref
from dataclasses import dataclass
from itertools import chain

import numpy as np

from ..shapes import KINDS
from .objects import OBJECT_MODELS

PLACEMENT_KEYS = ("name", "translate", "rotate", "scale")  # keys that never change what an object is


@dataclass(frozen=True, eq=False)
class Alike:
    """Sets of alike objects, numbered in the order of their first object."""
    of: np.ndarray     # (N,) int64: each object's set
    first: np.ndarray  # (K,) int64: each set's first object, which stands for all of its objects
    count: np.ndarray  # (K,) int64: objects in each set

    def firsts(self, objects) -> list:
        """The first object of each set: the one each set's decisions are taken on."""
        return [objects[i] for i in self.first.tolist()]

    def grouped(self, label: np.ndarray) -> list[np.ndarray]:
        """The objects (ascending) of each label 0..L-1, given the label of each set (K,): objects whose sets
        share a label form one group, in one stable sort rather than a pass per label."""
        labels = label[self.of]
        order = np.argsort(labels, kind="stable")
        return np.split(order, np.cumsum(np.bincount(labels))[:-1])


_CACHE: dict[int, tuple[weakref.ref, Alike]] = {}


def alike(scene) -> Alike:
    """The sets of alike objects of `scene.objects`, computed on first use and kept until the scene is freed (a
    Scene is frozen, so its objects cannot change under the cache)."""
    found = _CACHE.get(id(scene))
    if found is not None and found[0]() is scene:
        return found[1]
    sets = alike_of(scene.objects)
    key = id(scene)
    _CACHE[key] = (weakref.ref(scene, lambda _, key=key: _CACHE.pop(key, None)), sets)
    return sets


def alike_of(objects) -> Alike:
    """Number the distinct (shape, sizes, material, shading, normals, ...) tuples of `objects` in order."""
    count = len(objects)
    if not count:
        return Alike(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64))
    models = list(map(type, objects))
    distinct = dict.fromkeys(models)  # each kind of shape has its own model and keys (scene.objects)
    collecting = gc.isenabled()
    gc.disable()  # a million new key tuples would start as many collections of the growing heap (5× the time)
    try:
        if len(distinct) == 1:
            keys = list(map(_key_of(models[0]), objects))
        else:  # each object's own keys; the shape, among them, keeps two models' tuples apart
            getters = {model: _key_of(model) for model in distinct}
            keys = [getters[model](obj) for model, obj in zip(models, objects)]
    finally:
        if collecting:
            gc.enable()
    read = {OBJECT_MODELS[name] for name, kind in KINDS.items() if kind.from_file} & distinct.keys()
    for index in [i for i, model in enumerate(models) if model in read] if read else ():
        keys[index] = (index,)  # an object read from a file is a set of its own
    number = {key: k for k, key in enumerate(dict.fromkeys(keys))}
    of = np.fromiter(map(number.__getitem__, keys), np.int64, count)
    counts = np.bincount(of, minlength=len(number))
    seen = np.maximum.accumulate(of)  # set k first appears where it exceeds every set before it
    first = np.flatnonzero(np.concatenate(([True], of[1:] > seen[:-1])))
    return Alike(of, first, counts)


def _key_of(model) -> operator.attrgetter:
    """What an object of `model` is, placement aside: the tuple of its other keys' values."""
    return operator.attrgetter(*(key for key in model.model_fields if key not in PLACEMENT_KEYS))


def placements(objects, rows=None, keys=("scale", "rotate", "translate")) -> tuple[np.ndarray, ...]:
    """The `keys` (default: scale, rotate, translate), each (n, 3) float64, of the objects at `rows` (all when
    None): the numbers the scene holds, read in one pass per key."""
    picked = objects if rows is None else [objects[i] for i in np.asarray(rows).tolist()]
    n = len(picked)
    return tuple(np.fromiter(chain.from_iterable(map(operator.attrgetter(key), picked)), np.float64, 3 * n)
                 .reshape(n, 3) for key in keys)
