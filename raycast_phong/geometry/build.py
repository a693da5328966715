"""Build the scene's one world-space mesh, the Geometry: the one function that sequences the geometry stages.

The stages, each in its own module: group the objects that share a mesh (grouping.py), make each group's
template in the object frame (templates.py: a shape's triangles from shapes/, or a mesh file read by
io/meshes/read.py and mended by mesh_repair.py), place the group's objects and give them face and corner normals
(placing.py, normals.py), write the parts into one mesh (scene_mesh.py), give it material rows (file_materials.py),
textures (textures.py) and per-corner UVs and colours (corners.py), and check its range (checks.py). memo.py
decides which pieces are made afresh and which a live view's frames keep.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import partial

import numpy as np

from ..records import Geometry
from ..scene.alike import alike
from ..scene.schema import Scene
from .checks import check_float_range
from .corners import corner_colours, corner_uvs
from .file_materials import FileRows
from .grouping import object_groups, template_key
from .memo import FRESH, Memo
from .placing import place_group
from .scene_mesh import SceneMesh
from .templates import OBJECT_CHUNK_VERTICES, group_template
from .textures import TextureBank


def build_geometry(scene: Scene, vertex_normals: bool = True,
                   normal_dtype: type = np.float64, sources: dict | None = None,
                   memo: Memo = FRESH,
                   positions: Callable[[np.ndarray, np.ndarray], None] | None = None) -> Geometry:
    """Concatenate the scene's objects in world space, in the scene's order.

    Built-in objects that share a shape and its parameters (and normal rule) form one group: their mesh is
    built once and placed for all of them at once, so a scene of a million boxes costs a few numpy passes,
    not a million. A mesh file is a group of its own. Every per-object step is the same arithmetic in both
    cases (a batched matmul gives each object the bits of its own), so a group changes no pixel.
    `vertex_normals=False` (the plan's choice for an all-flat scene) leaves corner_normals empty;
    `normal_dtype` is the corner normals' dtype: render() asks for float32 when it shades in float32 (the
    kernel would round them so anyway), which halves the largest array of a smooth mesh. `sources`: the mesh
    files' io.meshes.source.MeshSource by resolved path (prepare() passes those the budget used; made here when
    not given).
    `memo` decides which pieces are made afresh: FRESH (a single render) makes every one; a BuildMemo (a live
    view's frames of one changing scene) keeps what the last build made and gives back what this scene shares
    with it. The Geometry is the same array for array.
    `positions(vertices, faces)` is told the Geometry's own vertices (V, 3) float64 and faces (F, 3) int32 once
    they are final: for a scene of one object (a mesh file) before its normals are made, else once every object
    is placed. prepare() starts the BVH then, while the normals are made.
    """
    sources = scene.current_mesh_sources() if sources is None else sources
    whole = memo.begin(scene, vertex_normals, normal_dtype)
    kept = memo.geometry_for(whole)
    if kept is not None:
        check_float_range(scene, kept)  # the lights it checks may be new (kept's box is kept)
        return kept
    try:
        geometry = _build(scene, vertex_normals, normal_dtype, memo, sources, positions)
    except BaseException:
        memo.abandon()  # keep the last good build's pieces only, however often a scene is refused
        raise
    memo.keep(whole, geometry)
    return geometry


def _build(scene: Scene, vertex_normals: bool, normal_dtype: type, memo: Memo, sources: dict | None,
           positions: Callable[[np.ndarray, np.ndarray], None] | None) -> Geometry:
    """build_geometry's work, each group's template, part and texture from `memo` when it has them."""
    material_index = {name: i + 1 for i, name in enumerate(scene.materials)}  # 0 is the built-in default
    groups = object_groups(scene)
    bank = TextureBank(scene, memo)
    notes, file_notes, file_rows = [], [], FileRows(scene, bank)
    built = []  # (members, template, exact corner normals in the object frame, a mesh file's material rows)
    for members in groups:
        index = int(members[0])
        wants_exact = vertex_normals and scene.objects[index].normals == "exact"
        group = memo.template(partial(template_key, scene, index, wants_exact, sources),
                              partial(group_template, scene, index, wants_exact, sources))
        file_notes += group.file_notes
        notes += group.notes
        rows = None  # a mesh file's own materials, unless the object names one: that paints the whole mesh
        if group.read is not None and scene.objects[index].material == "default":
            rows = file_rows.faces(group.read)
        built.append((members, group.template, group.exact, rows))
    mesh = SceneMesh.allocate(scene, built, vertex_normals, normal_dtype, material_index)
    for members, template, exact, rows in built:
        step = max(1, OBJECT_CHUNK_VERTICES // max(1, len(template.vertices)))
        for at in range(0, len(members), step):
            chunk = members[at:at + step]
            placed = mesh.placed_whole(positions) if mesh.single and positions else None
            mesh.write(memo.part(scene, chunk, template, vertex_normals, normal_dtype,
                                 partial(place_group, scene, chunk, template, exact, normal_dtype=normal_dtype,
                                         placed=placed)), rows)
    if positions is not None and not mesh.single:
        positions(mesh.vertices, mesh.faces)
    scene_maps = bank.scene_maps([o.material for o in alike(scene).firsts(scene.objects)])
    textured = bank.textures and (len(scene_maps) or file_rows.mapped)
    corner_uv = corner_uvs(scene, built, mesh) if textured else np.zeros((0, 3, 2), np.float32)
    corner_colour = corner_colours(scene, built, mesh, in_place=not memo.shares)
    geometry = mesh.geometry(tuple(notes), file_rows.table(), tuple(dict.fromkeys(file_notes + bank.notes)))
    geometry = dataclasses.replace(geometry, corner_uv=corner_uv, corner_colour=corner_colour,
                                   textures=tuple(bank.textures) if textured else (),
                                   scene_maps=scene_maps if textured else np.full((0, 3), -1, np.int64))
    check_float_range(scene, geometry)
    return geometry
