"""Global mode: shadow rays from every hit toward every light, answered by Embree occlusion queries.

For hit ray k the answer is a bit mask (bit j set: light j is visible), which the shading kernel
applies to light j's direct term (diffuse + specular) for every shading model, per pixel sample.

Two decisions keep shadows honest at any scale, both made in Embree's unit frame:
- *No self-shadowing*: Embree starts every ray at t = 0, so the origin is moved off the surface along the
  geometric normal, to the light's side, by OFFSET_ROUNDINGS float32 roundings of the largest coordinate
  involved (the face's corners, the origin): what Embree's float32 copy of the face and the stored origin can
  be off by, a few times over. The offset follows the hit's own rounding, not the scene's size: Wächter and
  Binder's 256 ulps (a fixed 1/65536 near the origin) leave a sheet 1e-5 of the scene above a plane without
  its shadow.
- *The shadow terminator* (Hanika, "Hacking the Shadow Terminator", Ray Tracing Gems II, ch. 4): for
  Gouraud and Phong faces with `terminator = "hanika"`, the origin first moves to where the smooth
  surface described by the vertex normals would be, so coarse facets do not shadow their own lit side.
"""

from __future__ import annotations

import numpy as np

from ...jit import kernel
from ...tolerances import MIN_DISTANCE
from .layout import POINT
from .ray_queries import occluded_rays
from .surface import facing_side, hit_point, to_light

OFFSET_ROUNDINGS = 8.0   # the shadow ray's origin leaves the surface by this many float32 roundings of `reach`
F32_ROUNDING = 2.0 ** -24  # float32's unit roundoff: a coordinate of magnitude x is stored within x · 2^-24
SHORT_OF_LIGHT = 1e-4    # embreex counts a hit exactly at tfar: stop this fraction short of a point light
FLOOR_SQUARED = MIN_DISTANCE ** 2  # the unit frame's half-extent is 1: a light this close is head-on


@kernel()
def no_shadow_rays(scene, inputs, face, u, v, directions, row_rays, visible):
    """Local mode's stand-in for cast_shadows, which render_band never calls there: no shadow rays cast."""
    return row_rays * 0


@kernel()
def cast_shadows(scene, inputs, face, u, v, directions, row_rays, visible):
    """Shadow rays from every hit of a tile toward every light, on Embree's C API scene
    (embree_library.EmbreeScene.scene): visible (N,) int64 light bits written in place (bit j set: light j is
    visible; 0 for a miss). Returns the number of shadow rays cast.

    The hits are taken in the primary packets' 4 × 4 blocks of an image row_rays rays wide, so that a
    packet of 16 shadow rays starts from neighbouring points (16 of one image row spread 4× wider)."""
    lights = inputs.light_kind.shape[0]
    count = face.shape[0]
    hits = 0
    for k in range(count):
        visible[k] = 0
        hits += face[k] >= 0
    hit_rays = np.empty(hits, np.int64)
    h = 0
    # The primary packets' 4 × 4 lane order, walked as ray_queries.fill_packets walks it: three loops inline
    # in each kernel (a helper taking the arrays costs a reference count per call; see ray_queries.camera_hits).
    for r0 in range(0, -(-count // row_rays), 4):
        for c0 in range(0, row_rays, 4):
            for lane in range(16):
                c = c0 + (lane & 3)
                k = (r0 + (lane >> 2)) * row_rays + c
                if c < row_rays and k < count and face[k] >= 0:
                    hit_rays[h] = k
                    h += 1
    origins = np.empty((hits * lights, 3), np.float32)
    toward = np.empty((hits * lights, 3), np.float32)
    t_max = np.empty(hits * lights, np.float32)
    shadow_rays(inputs, hit_rays, face, u, v, directions, origins, toward, t_max)
    blocked = np.empty(hits * lights, np.bool_)
    occluded_rays(scene, origins, toward, t_max, blocked)
    _gather_bits(hit_rays, ~blocked, lights, visible)
    return hits * lights


@kernel()
def shadow_rays(inputs, hit_rays, face, bu, bv, directions, origins, toward, t_max):
    """One shadow ray per hit and light (layout.ShadowInputs; the hits' face, u, v and ray directions): origins,
    unit directions toward (M, 3) float32 and t_max (M,) float32 in the unit frame written in place, for the
    hits hit_rays (H,) (M = H × K, light-minor)."""
    vertices, faces, face_normals, corner_normals = (inputs.vertices, inputs.faces, inputs.face_normals,
                                                     inputs.corner_normals)
    smooth, light_kind, light_vec = inputs.smooth, inputs.light_kind, inputs.light_vec
    two_sided, offset_scale = inputs.two_sided, inputs.offset_scale
    lights = light_kind.shape[0]
    for h in range(hit_rays.shape[0]):
        k = hit_rays[h]
        f = face[k]
        b1, b2 = float(bu[k]), float(bv[k])
        b0 = 1.0 - b1 - b2
        gx, gy, gz = face_normals[f, 0], face_normals[f, 1], face_normals[f, 2]
        # The viewer may see the back of a two-sided face: its smooth surface bulges toward the back.
        side = facing_side(gx, gy, gz, directions[k, 0], directions[k, 1], directions[k, 2], two_sided, 1.0)
        px, py, pz = hit_point(vertices, faces, f, b0, b1, b2)
        reach = 0.0  # the largest coordinate of the face's corners and of the origin (below)
        for j in range(3):
            vj = faces[f, j]
            reach = max(reach, abs(vertices[vj, 0]), abs(vertices[vj, 1]), abs(vertices[vj, 2]))
        if smooth[f]:
            # Hanika 2021: p' = Σ_j b_j (v_j + t_j), t_j = (p − v_j) with its part below corner j's tangent
            # plane removed; as Σ b_j (p − v_j) = 0 this is p − Σ_j b_j min(0, (p − v_j)·n_j) n_j.
            qx, qy, qz = px, py, pz
            for j in range(3):
                bj = b0 if j == 0 else (b1 if j == 1 else b2)
                vj = faces[f, j]
                n0, n1, n2 = (side * corner_normals[f, j, 0], side * corner_normals[f, j, 1],
                              side * corner_normals[f, j, 2])
                below = min(0.0, (px - vertices[vj, 0]) * n0 + (py - vertices[vj, 1]) * n1
                            + (pz - vertices[vj, 2]) * n2)
                qx, qy, qz = qx - bj * below * n0, qy - bj * below * n1, qz - bj * below * n2
            px, py, pz = qx, qy, qz
        reach = max(reach, abs(px), abs(py), abs(pz))
        for j in range(lights):
            r = h * lights + j
            point = light_kind[j] == POINT
            lx, ly, lz, _ = to_light(point, light_vec[j, 0], light_vec[j, 1], light_vec[j, 2], px, py, pz,
                                     gx, gy, gz, FLOOR_SQUARED)
            # Leave the surface on the light's side of the geometric normal, by OFFSET_ROUNDINGS float32 roundings
            # of the largest coordinate the hit's rounding involves (its face's corners, the point itself).
            toward_side = offset_scale if gx * lx + gy * ly + gz * lz >= 0 else -offset_scale
            step = toward_side * OFFSET_ROUNDINGS * F32_ROUNDING * reach
            ox, oy, oz = px + step * gx, py + step * gy, pz + step * gz
            t_max[r] = 1e37  # embreex's own "no limit"
            if point:
                lx, ly, lz, d = to_light(point, light_vec[j, 0], light_vec[j, 1], light_vec[j, 2], ox, oy, oz,
                                         gx, gy, gz, FLOOR_SQUARED)
                t_max[r] = d * (1.0 - SHORT_OF_LIGHT)
            origins[r, 0], origins[r, 1], origins[r, 2] = ox, oy, oz
            toward[r, 0], toward[r, 1], toward[r, 2] = lx, ly, lz


@kernel()
def _gather_bits(hit_rays, free, lights, visible):
    for h in range(hit_rays.shape[0]):
        mask = 0
        for j in range(lights):
            if free[h * lights + j]:
                mask |= 1 << j
        visible[hit_rays[h]] = mask
