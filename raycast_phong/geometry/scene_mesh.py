"""The scene's one mesh, allocated once its objects' sizes are known and written part by part (placing.Part)
in the scene's order, with each face's object, material row and shading model."""

from __future__ import annotations

import numpy as np

from ..codes import MODEL_CODE
from ..records import Geometry
from ..scene.alike import alike
from ..scene.schema import Scene
from .placing import Part


class SceneMesh:
    """The scene's one mesh, allocated once its objects' sizes are known and written part by part in the
    scene's order (face numbers and material rows follow the objects as the scene lists them)."""

    @classmethod
    def allocate(cls, scene: Scene, built: list, vertex_normals: bool, normal_dtype: type,
                 material_index: dict[str, int]) -> SceneMesh:
        mesh = cls()
        objects = len(scene.objects)
        mesh.vertex_count, mesh.face_count = np.zeros(objects, np.int64), np.zeros(objects, np.int64)
        for members, template, *_ in built:
            mesh.vertex_count[members] = len(template.vertices)
            mesh.face_count[members] = len(template.faces)
        mesh.vertex_start = np.cumsum(mesh.vertex_count) - mesh.vertex_count
        mesh.face_start = np.cumsum(mesh.face_count) - mesh.face_count
        # One object (a large mesh file) keeps its part's arrays: no copies.
        mesh.single = objects == 1
        vertices, faces = int(mesh.vertex_count.sum()), int(mesh.face_count.sum())
        if not mesh.single:
            mesh.vertices, mesh.unit = np.empty((vertices, 3)), np.empty((faces, 3))
            mesh.faces = np.empty((faces, 3), np.int32)  # filled part by part: no int64 copies
            mesh.corners = np.empty((faces if vertex_normals else 0, 3, 3), normal_dtype)
        else:
            mesh.corners = np.zeros((0, 3, 3), normal_dtype)
            mesh.faces = None  # the part's, in int32 (write, or placed_whole before its normals)
        mesh.face_object = np.repeat(np.arange(objects, dtype=np.int32), mesh.face_count)
        sets = alike(scene)  # material and shading are decided per set of alike objects
        firsts = sets.firsts(scene.objects)
        object_material = np.array([material_index.get(o.material, 0) for o in firsts], np.int32)[sets.of]
        mesh.face_material = object_material[mesh.face_object]
        object_model = np.array([MODEL_CODE[scene.shading_of(o)] for o in firsts], np.int8)[sets.of]
        mesh.face_model = object_model[mesh.face_object]
        return mesh

    def placed_whole(self, positions):
        """For placing.place_group of the one object (`single`): a callback that takes its placed vertices and faces
        as the mesh's own (the faces in int32, made once) and tells `positions(vertices, faces)` of them."""
        def placed(vertices: np.ndarray, faces: np.ndarray) -> None:
            self.vertices, self.faces = vertices, faces.astype(np.int32)
            positions(self.vertices, self.faces)
        return placed

    def write(self, part: Part, rows: np.ndarray | None) -> None:
        """Copy a part's objects into their places; `rows`: a mesh file's own material rows for its faces."""
        members = part.members
        if rows is not None:
            start = self.face_start[members[0]]
            self.face_material[start:start + len(rows)] = rows
        if self.single:
            self.vertices, self.unit = part.vertices[0], part.unit[0]
            if self.faces is None:  # else placed_whole's (the same numbers)
                self.faces = part.faces[0].astype(np.int32)
            if part.corners is not None:
                self.corners = part.corners[0]
            return
        if members[-1] - members[0] + 1 == len(members):  # consecutive objects (the usual case): one slice each
            at_vertex = slice(self.vertex_start[members[0]], self.vertex_start[members[-1]] + part.vertices.shape[1])
            at_face = slice(self.face_start[members[0]], self.face_start[members[-1]] + part.faces.shape[1])
        else:
            at_vertex = (self.vertex_start[members][:, None] + np.arange(part.vertices.shape[1])).ravel()
            at_face = (self.face_start[members][:, None] + np.arange(part.faces.shape[1])).ravel()
        self.vertices[at_vertex] = part.vertices.reshape(-1, 3)
        self.faces[at_face] = (part.faces + self.vertex_start[members][:, None, None]).reshape(-1, 3)
        self.unit[at_face] = part.unit.reshape(-1, 3)
        if part.corners is not None:
            self.corners[at_face] = part.corners.reshape(-1, 3, 3)

    def geometry(self, notes: tuple, file_materials: np.ndarray, file_notes: tuple) -> Geometry:
        return Geometry(vertices=self.vertices, faces=self.faces, face_normals=self.unit,
                        corner_normals=self.corners, face_material=self.face_material, face_model=self.face_model,
                        face_object=self.face_object, notes=notes, file_materials=file_materials,
                        file_notes=file_notes)
