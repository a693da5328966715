"""Flat, Gouraud and Phong shading: where the illumination model is evaluated, and how it is interpolated.

This is where a pixel's colour is decided (`_shade_rays`). Per hit, by the face's shading model:
  flat     the model once at the triangle's centroid with its face normal, held across the face;
  gouraud  the model at the three corners with their vertex normals, mixed with the hit's weights;
  phong    the vertex normals mixed with the hit's weights and renormalised (the face normal if the
           mix has no length), and the model at the hit point.
Weights are Embree's (perspective-correct: the true point on the triangle) or, with
interpolation = "screen", linear in the image plane like the lecture's scanline formulas.
Two-sided shading flips the normals of a back-facing hit toward the viewer. Shading runs in a frame
centred on the scene (translation changes no direction or distance) in the scene's precision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from .camera import CameraRig
from .illumination import (AMBIENT, COUNTED_TERMS, DIFFUSE, EMISSION, F_AOV_GEOMETRY, F_AOV_TERMS, F_SCREEN,
                           F_TWO_SIDED, SPECULAR, illuminate)
from .intersect import TileHits
from .records import Frame, Geometry
from .scene import DEFAULT_MATERIAL, Scene


@dataclass(frozen=True, eq=False)
class ShadingInputs:
    """Everything the shading kernel reads, in the scene's precision, centred on the scene."""
    vertices: np.ndarray        # (V, 3)
    faces: np.ndarray           # (F, 3) int32
    face_normals: np.ndarray    # (F, 3)
    corner_normals: np.ndarray  # (F, 3, 3), or (1, 3, 3) of zeros when no face is smooth-shaded
    face_material: np.ndarray   # (F,) int32
    face_model: np.ndarray      # (F,) int8
    ka: np.ndarray              # (M, 3) material coefficients; row 0 is the built-in default
    kd: np.ndarray
    ks: np.ndarray
    ke: np.ndarray
    shininess: np.ndarray       # (M,)
    light_kind: np.ndarray      # (K,) int64, 0 point, 1 directional
    light_vec: np.ndarray       # (K, 3) point: position; directional: unit vector toward the light
    light_id: np.ndarray        # (K, 3) I_d
    light_is: np.ndarray        # (K, 3) I_s
    light_ia: np.ndarray        # (K, 3) per-light ambient
    light_att_kind: np.ndarray  # (K,) int64, 0 none, 1 inverse square, 2 [c, l, q]
    light_att: np.ndarray       # (K, 3) c, l, q
    ambient: np.ndarray         # (3,) I_a
    eye: np.ndarray             # (3,) camera position
    fixed_view: np.ndarray      # (3,) v for an infinite viewer or an orthographic camera: −forward
    camera: np.ndarray          # (11,) right, up, forward, orthographic (1/0), in the centred frame
    flags: np.ndarray           # (FLAG_COUNT,) int64, from the render plan
    constants: np.ndarray       # (4,) 0, 1, 2, tiny in the precision's dtype
    frame_scale: float          # Embree's unit-frame t × frame_scale = world distance


def prepare_shading(scene: Scene, geometry: Geometry, rig: CameraRig, frame: Frame, flags: np.ndarray) -> ShadingInputs:
    """Pack the scene's numbers into arrays of the scene's precision for the kernel."""
    real = np.float32 if scene.render.precision == "float32" else np.float64
    center = frame.center

    def arr(values, dtype=real):
        return np.ascontiguousarray(np.asarray(values, np.float64), dtype=dtype)

    materials = [DEFAULT_MATERIAL, *scene.materials.values()]
    lights = scene.lights
    kinds = [0 if light.type == "point" else 1 for light in lights]
    vectors = []
    for light in lights:
        if light.type == "point":
            vectors.append(np.asarray(light.position) - center)
        else:
            direction = -np.asarray(light.direction, np.float64)
            vectors.append(direction / np.linalg.norm(direction))
    att_kind, att = [], []
    for light in lights:
        if light.type == "directional" or light.attenuation == "none":
            att_kind.append(0), att.append((1.0, 0.0, 0.0))
        elif light.attenuation == "inverse_square":
            att_kind.append(1), att.append((0.0, 0.0, 1.0))
        else:
            att_kind.append(2), att.append(light.attenuation)
    corner = geometry.corner_normals if len(geometry.corner_normals) else np.zeros((1, 3, 3))
    camera = np.concatenate([rig.right, rig.up, rig.forward, [float(rig.orthographic)], [0.0]])
    return ShadingInputs(
        vertices=arr(geometry.vertices - center),
        faces=np.ascontiguousarray(geometry.faces, np.int32),
        face_normals=arr(geometry.face_normals),
        corner_normals=arr(corner),
        face_material=np.ascontiguousarray(geometry.face_material, np.int32),
        face_model=np.ascontiguousarray(geometry.face_model, np.int8),
        ka=arr([m.ka for m in materials]), kd=arr([m.kd for m in materials]),
        ks=arr([m.ks for m in materials]), ke=arr([m.ke for m in materials]),
        shininess=arr([m.shininess for m in materials]),
        light_kind=np.asarray(kinds, np.int64).reshape(-1),
        light_vec=arr(vectors).reshape(-1, 3),
        light_id=arr([l.diffuse for l in lights]).reshape(-1, 3),
        light_is=arr([l.specular for l in lights]).reshape(-1, 3),
        light_ia=arr([l.ambient for l in lights]).reshape(-1, 3),
        light_att_kind=np.asarray(att_kind, np.int64).reshape(-1),
        light_att=arr(att).reshape(-1, 3),
        ambient=arr(scene.ambient),
        eye=arr(rig.eye - center),
        fixed_view=arr(-rig.forward),
        camera=arr(camera),
        flags=np.ascontiguousarray(flags, np.int64),
        constants=np.array([0, 1, 2, np.finfo(real).tiny], real),
        frame_scale=frame.scale,
    )


@dataclass(frozen=True, eq=False)
class TileImage:
    """Shaded rows [row0, row1) of the image and of the requested layers."""
    rgb: np.ndarray     # (rows, W, 3) float32
    terms: np.ndarray   # (rows, W, 4, 3) float32 ambient, diffuse, specular, emission; (0, 0, 4, 3) if not asked
    depth: np.ndarray   # (rows, W) float32, world distance along the ray; inf on a miss; (0, 0) if not asked
    normal: np.ndarray  # (rows, W, 3) float32 shading normal; 0 on a miss
    face: np.ndarray    # (rows, W) float32 face index, -1 on a miss
    counts: np.ndarray  # (len(COUNTED_TERMS),) int64


def shade_tile(inputs: ShadingInputs, hits: TileHits, directions: np.ndarray, rows: int, width: int,
               samples: int, background: np.ndarray) -> TileImage:
    """Colour of every pixel of a tile from its rays' closest hits (mean over the n×n samples)."""
    geometry_layers = bool(inputs.flags[F_AOV_GEOMETRY])
    term_layers = bool(inputs.flags[F_AOV_TERMS])
    g_rows = rows if geometry_layers else 0
    tile = TileImage(
        rgb=np.zeros((rows, width, 3), np.float32),
        terms=np.zeros((rows if term_layers else 0, width if term_layers else 0, 4, 3), np.float32),
        depth=np.full((g_rows, width if geometry_layers else 0), np.inf, np.float32),
        normal=np.zeros((g_rows, width if geometry_layers else 0, 3), np.float32),
        face=np.full((g_rows, width if geometry_layers else 0), -1.0, np.float32),
        counts=np.zeros(len(COUNTED_TERMS), np.int64),
    )
    i = inputs
    _shade_rays(hits.face, hits.u, hits.v, hits.t, directions, samples, width, i.frame_scale,
                i.vertices, i.faces, i.face_normals, i.corner_normals, i.face_material, i.face_model,
                i.ka, i.kd, i.ks, i.ke, i.shininess, i.light_kind, i.light_vec, i.light_id, i.light_is,
                i.light_ia, i.light_att_kind, i.light_att, i.ambient, np.asarray(background, np.float32),
                i.eye, i.fixed_view, i.camera, i.flags, i.constants,
                tile.rgb, tile.terms, tile.depth, tile.normal, tile.face, tile.counts)
    return tile


@njit(cache=True, nogil=True)
def _project(x, y, z, eye, camera):
    """Image-plane coordinates of a point: (x/z, y/z) in the camera frame, or (x, y) if orthographic."""
    rx, ry, rz = x - eye[0], y - eye[1], z - eye[2]
    cx = rx * camera[0] + ry * camera[1] + rz * camera[2]
    cy = rx * camera[3] + ry * camera[4] + rz * camera[5]
    if camera[9] != 0:
        return cx, cy
    cz = rx * camera[6] + ry * camera[7] + rz * camera[8]
    return cx / cz, cy / cz


@njit(cache=True, nogil=True)
def _screen_weights(b0, b1, b2, v, f0, f1, f2, eye, camera, one):
    """Barycentric weights of the hit's image-plane position in the projected triangle.

    The hit's own image position is the projection of the true hit point (b0 v0 + b1 v1 + b2 v2).
    """
    px = b0 * v[f0, 0] + b1 * v[f1, 0] + b2 * v[f2, 0]
    py = b0 * v[f0, 1] + b1 * v[f1, 1] + b2 * v[f2, 1]
    pz = b0 * v[f0, 2] + b1 * v[f1, 2] + b2 * v[f2, 2]
    sx, sy = _project(px, py, pz, eye, camera)
    ax, ay = _project(v[f0, 0], v[f0, 1], v[f0, 2], eye, camera)
    bx, by = _project(v[f1, 0], v[f1, 1], v[f1, 2], eye, camera)
    cx, cy = _project(v[f2, 0], v[f2, 1], v[f2, 2], eye, camera)
    area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    if area == 0:
        return b0, b1, b2  # an edge-on triangle has no screen area: keep the true weights
    w1 = ((sx - ax) * (cy - ay) - (cx - ax) * (sy - ay)) / area
    w2 = ((bx - ax) * (sy - ay) - (sx - ax) * (by - ay)) / area
    return one - w1 - w2, w1, w2


@njit(cache=True, nogil=True)
def _shade_rays(face, bu, bv, tfar, directions, samples, width, frame_scale,
                vertices, faces, face_normals, corner_normals, face_material, face_model,
                ka, kd, ks, ke, shininess, light_kind, light_vec, light_id, light_is, light_ia,
                light_att_kind, light_att, ambient, background, eye, fixed_view, camera, flags, c,
                rgb, terms, depth, normal, face_out, counts):
    zero, one = c[0], c[1]
    third = one / (one + one + one)
    per_pixel = samples * samples
    weight = one / (one * per_pixel)
    centre_sample = (samples // 2) * samples + samples // 2  # the geometric layers come from this sample
    acc = np.zeros((4, 3), c.dtype)
    for k in range(face.shape[0]):
        pixel, sample = k // per_pixel, k % per_pixel
        row, col = pixel // width, pixel % width
        f = face[k]
        geometry_sample = flags[F_AOV_GEOMETRY] != 0 and sample == centre_sample
        if f < 0:
            for ch in range(3):
                rgb[row, col, ch] += weight * background[ch]
            continue

        i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
        b1, b2 = one * bu[k], one * bv[k]
        b0 = one - b1 - b2
        if flags[F_SCREEN]:
            b0, b1, b2 = _screen_weights(b0, b1, b2, vertices, i0, i1, i2, eye, camera, one)
        gx, gy, gz = face_normals[f, 0], face_normals[f, 1], face_normals[f, 2]
        side = one
        if flags[F_TWO_SIDED] and gx * directions[k, 0] + gy * directions[k, 1] + gz * directions[k, 2] > 0:
            side = -one  # the ray sees the back: shade the side that faces the viewer
        m = face_material[f]
        model = face_model[f]
        acc[:] = zero
        nx, ny, nz = side * gx, side * gy, side * gz
        if model == 0:
            px = (vertices[i0, 0] + vertices[i1, 0] + vertices[i2, 0]) * third
            py = (vertices[i0, 1] + vertices[i1, 1] + vertices[i2, 1]) * third
            pz = (vertices[i0, 2] + vertices[i1, 2] + vertices[i2, 2]) * third
            illuminate(px, py, pz, nx, ny, nz, m, one, ka, kd, ks, ke, shininess, light_kind, light_vec,
                       light_id, light_is, light_ia, light_att_kind, light_att, ambient, eye, fixed_view,
                       flags, c, acc, counts)
        elif model == 1:
            for j in range(3):
                vj = faces[f, j]
                bj = b0 if j == 0 else (b1 if j == 1 else b2)
                illuminate(vertices[vj, 0], vertices[vj, 1], vertices[vj, 2],
                           side * corner_normals[f, j, 0], side * corner_normals[f, j, 1],
                           side * corner_normals[f, j, 2], m, bj, ka, kd, ks, ke, shininess, light_kind,
                           light_vec, light_id, light_is, light_ia, light_att_kind, light_att, ambient, eye,
                           fixed_view, flags, c, acc, counts)
            if geometry_sample:
                nx = side * (b0 * corner_normals[f, 0, 0] + b1 * corner_normals[f, 1, 0] + b2 * corner_normals[f, 2, 0])
                ny = side * (b0 * corner_normals[f, 0, 1] + b1 * corner_normals[f, 1, 1] + b2 * corner_normals[f, 2, 1])
                nz = side * (b0 * corner_normals[f, 0, 2] + b1 * corner_normals[f, 1, 2] + b2 * corner_normals[f, 2, 2])
        else:
            px = b0 * vertices[i0, 0] + b1 * vertices[i1, 0] + b2 * vertices[i2, 0]
            py = b0 * vertices[i0, 1] + b1 * vertices[i1, 1] + b2 * vertices[i2, 1]
            pz = b0 * vertices[i0, 2] + b1 * vertices[i1, 2] + b2 * vertices[i2, 2]
            sx = b0 * corner_normals[f, 0, 0] + b1 * corner_normals[f, 1, 0] + b2 * corner_normals[f, 2, 0]
            sy = b0 * corner_normals[f, 0, 1] + b1 * corner_normals[f, 1, 1] + b2 * corner_normals[f, 2, 1]
            sz = b0 * corner_normals[f, 0, 2] + b1 * corner_normals[f, 1, 2] + b2 * corner_normals[f, 2, 2]
            length = math.sqrt(sx * sx + sy * sy + sz * sz)
            if length > zero:
                nx, ny, nz = side * sx / length, side * sy / length, side * sz / length
            illuminate(px, py, pz, nx, ny, nz, m, one, ka, kd, ks, ke, shininess, light_kind, light_vec,
                       light_id, light_is, light_ia, light_att_kind, light_att, ambient, eye, fixed_view,
                       flags, c, acc, counts)

        for ch in range(3):
            rgb[row, col, ch] += weight * (acc[AMBIENT, ch] + acc[DIFFUSE, ch] + acc[SPECULAR, ch] + acc[EMISSION, ch])
        if flags[F_AOV_TERMS]:
            for term in range(4):
                for ch in range(3):
                    terms[row, col, term, ch] += weight * acc[term, ch]
        if geometry_sample:
            depth[row, col] = tfar[k] * frame_scale
            face_out[row, col] = f
            length = math.sqrt(nx * nx + ny * ny + nz * nz)
            if length > 0:
                normal[row, col, 0], normal[row, col, 1], normal[row, col, 2] = nx / length, ny / length, nz / length
