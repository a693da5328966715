"""Flat, Gouraud and Phong shading: where the illumination model is evaluated, and how it is interpolated.

This is where a pixel's colour is decided (`_shade_rays`). Per hit, by the face's shading model:
  flat     the model once at the triangle's centroid with its face normal, held across the face;
  gouraud  the model at the three corners with their vertex normals, mixed with the hit's weights;
  phong    the vertex normals mixed with the hit's weights and renormalised (the face normal if the
           mix has no length), and the model at the hit point.
Weights are Embree's (perspective-correct: the true point on the triangle) or, with
interpolation = "screen", linear in the image plane like the lecture's scanline formulas.
Colour maps and vertex colours (only when the scene has them: F_TEXTURES, F_VERTEX_COLOURS) modulate the
material per pixel: the k_d map's colour at the hit's interpolated UV multiplies k_d, the k_a map's (the k_d
map unless the file gives its own) k_a, the k_e map's k_e; k_s is never textured (the fixed-function
"modulate" with a separate specular). Each model then keeps its lighting rule with that material, so flat
and Gouraud show the texture per pixel too. Vertex colours multiply k_a and k_d as glTF's COLOR_0 does:
Phong at the hit (interpolated), Gouraud per corner (each corner lit with its own colour, as GL does),
flat one colour per face (the mean of its corners: the colour at the centroid it is lit at).
Two-sided shading flips the normals of a back-facing hit toward the viewer. Shading runs in a frame
centred on the scene (translation changes no direction or distance) in the scene's precision.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from ...jit import kernel
from ...tolerances import NO_DIRECTION
from .illumination import attenuation, diffuse_terms, highlight_cosine, illuminate, specular_terms, view_direction
from .layout import (
    ATTENUATION_NONE,
    C_ATTENUATION,
    C_DIFFUSE,
    C_EMISSION,
    C_LIGHT_AMBIENT,
    C_SCENE_AMBIENT,
    C_SPECULAR,
    C_VIEW,
    CAM_FORWARD,
    CAM_ORTHOGRAPHIC,
    CAM_RIGHT,
    CAM_UP,
    F_AOV_GEOMETRY,
    F_AOV_TERMS,
    F_ATTENUATION,
    F_DIFFUSE,
    F_EMISSION,
    F_LIGHT_AMBIENT,
    F_SCENE_AMBIENT,
    F_SCREEN,
    F_SHADOWS,
    F_TEXTURES,
    F_TWO_SIDED,
    F_VERTEX_COLOURS,
    F_VIEW_PER_POINT,
    FLAT,
    GOURAUD,
    KA,
    KA_MAP,
    KD,
    KD_MAP,
    KE,
    KE_MAP,
    KS,
    L_ATT,
    L_ATT_KIND,
    L_IA,
    L_ID,
    L_IS,
    L_KIND,
    L_VEC,
    PHONG,
    POINT,
    SHININESS,
    SPECULAR_NONE,
    TERMS,
    V_AMBIENT,
    V_EYE,
    V_FLOOR,
    V_VIEW,
    Material,
)
from .surface import facing_side, hit_point, to_light
from .texture import sample

AHEAD = 16  # rays between a face row's prefetch and its use (8: no better, ico6 1000²)
PACKET = 16  # rays shaded together where the scene allows (_shade_rays)
LANES = 16  # the packet's per-hit values between its passes
ALL_VISIBLE = -1  # every bit set: local mode, no light is ever shadowed


@intrinsic
def _prefetch(typingctx, array, index):
    """llvm.prefetch of the element at flat `index` of a C-contiguous array (read, keep in every cache level):
    a hint to the CPU, no result and no fault (an index past the end is never read)."""
    def codegen(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        byte = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        pointer = builder.bitcast(builder.gep(ary.data, [args[1]]), byte)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [byte, i32, i32, i32]),
                                            "llvm.prefetch.p0")
        builder.call(fn, [pointer, i32(0), i32(3), i32(1)])
        return context.get_dummy_value()
    return types.void(array, types.intp), codegen


@kernel()
def _project(x, y, z, eye, camera):
    """Image-plane coordinates of a point, (x/z, y/z) in the camera frame or (x, y) if orthographic, and
    its depth z along the view direction (1 if orthographic: every point projects)."""
    rx, ry, rz = x - eye[0], y - eye[1], z - eye[2]
    cx = rx * camera[CAM_RIGHT] + ry * camera[CAM_RIGHT + 1] + rz * camera[CAM_RIGHT + 2]
    cy = rx * camera[CAM_UP] + ry * camera[CAM_UP + 1] + rz * camera[CAM_UP + 2]
    if camera[CAM_ORTHOGRAPHIC] != 0:
        return cx, cy, camera[CAM_ORTHOGRAPHIC]
    cz = rx * camera[CAM_FORWARD] + ry * camera[CAM_FORWARD + 1] + rz * camera[CAM_FORWARD + 2]
    # At or behind the eye plane a point has no image: report its depth and let the caller refuse it.
    return (cx / cz, cy / cz, cz / math.sqrt(rx * rx + ry * ry + rz * rz)) if cz > 0 else (cx, cy, cz)


@kernel()
def _screen_weights(b0, b1, b2, v, f0, f1, f2, eye, camera, one):
    """Barycentric weights of the hit's image-plane position in the projected triangle.

    The hit's own image position is the projection of the true hit point (b0 v0 + b1 v1 + b2 v2).
    A triangle with a corner at or behind the eye plane has no projected triangle to interpolate in
    (its "weights" would leave [0, 1], e.g. (0.56, 0.56, −0.12)): it keeps the true weights, as does an
    edge-on one. "At" means within NO_DIRECTION of the plane, as a cosine, so that 1/z stays finite.
    """
    px = b0 * v[f0, 0] + b1 * v[f1, 0] + b2 * v[f2, 0]
    py = b0 * v[f0, 1] + b1 * v[f1, 1] + b2 * v[f2, 1]
    pz = b0 * v[f0, 2] + b1 * v[f1, 2] + b2 * v[f2, 2]
    ax, ay, az = _project(v[f0, 0], v[f0, 1], v[f0, 2], eye, camera)
    bx, by, bz = _project(v[f1, 0], v[f1, 1], v[f1, 2], eye, camera)
    cx, cy, cz = _project(v[f2, 0], v[f2, 1], v[f2, 2], eye, camera)
    if min(az, bz, cz) <= NO_DIRECTION:
        return b0, b1, b2
    sx, sy, _ = _project(px, py, pz, eye, camera)
    area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    if area == 0:
        return b0, b1, b2  # an edge-on triangle has no screen area: keep the true weights
    w1 = ((sx - ax) * (cy - ay) - (cx - ax) * (sy - ay)) / area
    w2 = ((bx - ax) * (sy - ay) - (sx - ax) * (by - ay)) / area
    return one - w1 - w2, w1, w2


@kernel(inline="always")
def _mixed_normal(corner_normals, f, b0, b1, b2):
    """b0 n0 + b1 n1 + b2 n2: face f's vertex normals mixed with barycentric weights (not renormalised)."""
    return (b0 * corner_normals[f, 0, 0] + b1 * corner_normals[f, 1, 0] + b2 * corner_normals[f, 2, 0],
            b0 * corner_normals[f, 0, 1] + b1 * corner_normals[f, 1, 1] + b2 * corner_normals[f, 2, 1],
            b0 * corner_normals[f, 0, 2] + b1 * corner_normals[f, 1, 2] + b2 * corner_normals[f, 2, 2])


@kernel(inline="always")
def _material_row(materials, m):
    """Material m's row (layout's KA, KD, KS, KE, SHININESS columns) as a Material: read once per run of hits of
    one material, by the packets and by the one-hit loop alike."""
    return Material(materials[m, KA], materials[m, KA + 1], materials[m, KA + 2], materials[m, KD],
                    materials[m, KD + 1], materials[m, KD + 2], materials[m, KS], materials[m, KS + 1],
                    materials[m, KS + 2], materials[m, KE], materials[m, KE + 1], materials[m, KE + 2],
                    materials[m, SHININESS])


@kernel(inline="always")
def _modulated(m, r, g, b):
    """Material m with k_a and k_d multiplied by the colour (r, g, b): a texture's or a vertex colour."""
    return Material(m.ka_r * r, m.ka_g * g, m.ka_b * b, m.kd_r * r, m.kd_g * g, m.kd_b * b, m.ks_r, m.ks_g,
                    m.ks_b, m.ke_r, m.ke_g, m.ke_b, m.shininess)


@kernel(inline="always")
def _textured_material(materials, texels, table, uvs, density, material, m, f, b0, b1, b2, footprint, one, cast):
    """The material at a hit with its colour maps applied: each map sampled at the hit's UV (the corners'
    UVs mixed with the weights b), k_a, k_d and k_e multiplied (texture.py chooses the level from
    `footprint`, the sample's world size, times the face's texels per world length). `cast` (3,) in the
    shading precision: a sample passes through it, so the material keeps the precision of the untextured
    path (numba would widen a float32 Material to float64 for every pixel otherwise)."""
    ka_map, kd_map, ke_map = int(materials[m, KA_MAP]), int(materials[m, KD_MAP]), int(materials[m, KE_MAP])
    if ka_map < 0 and kd_map < 0 and ke_map < 0:
        return material
    u = b0 * uvs[f, 0, 0] + b1 * uvs[f, 1, 0] + b2 * uvs[f, 2, 0]
    v = b0 * uvs[f, 0, 1] + b1 * uvs[f, 1, 1] + b2 * uvs[f, 2, 1]
    per_length = footprint * density[f]
    ar = ag = ab = dr = dg = db = er = eg = eb = one
    if kd_map >= 0:
        r, g, b = sample(texels, table, kd_map, u, v, per_length * math.sqrt(table[kd_map, 1] * table[kd_map, 2]))
        cast[0], cast[1], cast[2] = r, g, b
        dr, dg, db = cast[0], cast[1], cast[2]
    if ka_map == kd_map:
        ar, ag, ab = dr, dg, db
    elif ka_map >= 0:
        r, g, b = sample(texels, table, ka_map, u, v, per_length * math.sqrt(table[ka_map, 1] * table[ka_map, 2]))
        cast[0], cast[1], cast[2] = r, g, b
        ar, ag, ab = cast[0], cast[1], cast[2]
    if ke_map >= 0:
        r, g, b = sample(texels, table, ke_map, u, v, per_length * math.sqrt(table[ke_map, 1] * table[ke_map, 2]))
        cast[0], cast[1], cast[2] = r, g, b
        er, eg, eb = cast[0], cast[1], cast[2]
    return Material(material.ka_r * ar, material.ka_g * ag, material.ka_b * ab, material.kd_r * dr,
                    material.kd_g * dg, material.kd_b * db, material.ks_r, material.ks_g, material.ks_b,
                    material.ke_r * er, material.ke_g * eg, material.ke_b * eb, material.shininess)


@kernel(inline="always")
def _next_sample(sample, col, row, per_pixel, width):
    """The sample, column and row of the next ray: ray k is sample k % n² of pixel k // n², in rows of `width`
    pixels (counters keep integer division out of the hot loop; scalars only, so inlining costs nothing)."""
    sample += 1
    if sample == per_pixel:
        sample, col = 0, col + 1
        if col == width:
            col, row = 0, row + 1
    return sample, col, row


@kernel()
def _shade_rays(inputs, rays, film):
    """Shade every ray of a tile into the film rows (ShadingInputs, TileRays, FilmRows).

    Where the scene allows (see `packets` below) 16 rays are shaded together, their vector math in SIMD
    lanes; every other ray goes through one loop, kept whole on purpose: moving the Gouraud corners, the
    Phong normal and the film writes into inlined helpers measured 8–15 % more CPU time per tile
    (thread_time, min of 40, 600² sphere). Arrays
    come out of their tuples once, here: a field read per hit costs a reference count, and so does a
    row view such as directions[k] (it made the frame 15–28 % slower until the scalars were passed).
    """
    vertices, faces, face_normals = inputs.vertices, inputs.faces, inputs.face_normals
    corner_normals, face_material, face_model = inputs.corner_normals, inputs.face_material, inputs.face_model
    materials, lights, view = inputs.materials, inputs.lights, inputs.viewing
    camera, background = inputs.camera, inputs.background
    flags, specular, zero, one, two = inputs.flags, inputs.specular, inputs.zero, inputs.one, inputs.two
    face, bu, bv, tfar, directions, visible, samples = rays
    rgb, terms, depth, normal, face_out, counts = film
    width = rgb.shape[1]
    eye = view[V_EYE:V_EYE + 3]
    # The whole viewing row (layout.VIEWING_SIZE) as a tuple: illuminate reads it by layout's names.
    view_tuple = (view[0], view[1], view[2], view[3], view[4], view[5], view[6], view[7], view[8], view[9])
    third = one / (one + one + one)
    per_pixel = samples * samples
    weight = one / (one * per_pixel)
    centre_sample = (samples // 2) * samples + samples // 2  # the geometric layers come from this sample
    geometry_layers, term_layers = flags & F_AOV_GEOMETRY != 0, flags & F_AOV_TERMS != 0
    two_sided, screen, shadows = flags & F_TWO_SIDED != 0, flags & F_SCREEN != 0, flags & F_SHADOWS != 0
    textured, coloured = flags & F_TEXTURES != 0, flags & F_VERTEX_COLOURS != 0
    colours, spread = inputs.corner_colour, inputs.pixel_spread
    texels, texture_table = inputs.texels, inputs.texture_table
    corner_uv, uv_density = inputs.corner_uv, inputs.uv_density
    orthographic = camera[CAM_ORTHOGRAPHIC] != 0
    cast = np.zeros(3, materials.dtype)
    evaluated = np.zeros(len(counts), np.int64)
    # The film starts at zero, so a black background needs no writes at all.
    has_background = background[0] != 0 or background[1] != 0 or background[2] != 0
    # Ray k is sample k % n² of pixel k // n² (_next_sample).
    row, col, sample = 0, 0, -1
    # Hits of one run share their material row and their mask of evaluated terms: the row is read once per
    # run of hits of one material, and a run's mask is counted once when it ends (not 7 counters per hit).
    last_m, run_mask, run_length = -1, 0, 0
    base = Material(zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero)
    # Packets: with one light (point or directional, any attenuation, either highlight or none, any viewer) and
    # no maps, colours or screen weights, PACKET rays whose hits are all Phong faces of one material (misses
    # allowed) are shaded in three passes: their rows gathered (A); normal, view and light vectors, f_att, n·l
    # and the highlight's cosine computed lane by lane, which LLVM vectorises (B: vsqrtps, vdivps on zmm); then,
    # in ray order, the terms (powf stays scalar: an own vectorisable power measured slower on every other path,
    # docs/performance.md), counts and film (C). Each hit gets illuminate's operations in its order, so the
    # image is bit-identical to the one-hit-at-a-time loop below (tests: test_shading.py, one case per kind of
    # light), 24-31 % less shading CPU time on ico6 1000². The rules stay illuminate's: this is its one-light
    # case written out by lanes. A packet of sixteen misses, in any scene, only moves the pixel counters (and
    # adds the background).
    packets = not textured and not coloured and not screen and lights.shape[0] == 1
    # The packet's light, as illuminate reads it: its kind, its attenuation (if the scene asks for any), and
    # whether the viewer is per point (only the highlight reads v).
    point_light = lights.shape[0] > 0 and lights[0, L_KIND] == POINT
    falloff = lights[0, L_ATT_KIND] if packets and flags & F_ATTENUATION else ATTENUATION_NONE
    per_point = specular != SPECULAR_NONE and flags & F_VIEW_PER_POINT != 0
    lane = np.empty((LANES, PACKET), vertices.dtype)
    fixed = 0
    if flags & F_EMISSION:
        fixed |= 1 << C_EMISSION
    if flags & F_SCENE_AMBIENT:
        fixed |= 1 << C_SCENE_AMBIENT
    if per_point:
        fixed |= 1 << C_VIEW
    if falloff != ATTENUATION_NONE:
        fixed |= 1 << C_ATTENUATION
    if flags & F_LIGHT_AMBIENT:
        fixed |= 1 << C_LIGHT_AMBIENT
    done_until = 0
    for k in range(face.shape[0]):
        if k < done_until:
            continue
        usable, first_m = False, -1
        if k % PACKET == 0 and k + PACKET <= face.shape[0]:
            # One scan of the sixteen: whether all miss, and (where the scene allows packets) whether their hits
            # are all Phong faces of one material, first_m.
            missed, usable = True, packets
            for j in range(PACKET):
                fj = face[k + j]
                if fj >= 0:
                    missed = False
                    if not usable:
                        break
                    if face_model[fj] != PHONG or (first_m >= 0 and face_material[fj] != first_m):
                        usable = False
                        break
                    first_m = face_material[fj]
            if missed:  # sixteen misses (most of ico6's misses): the background at most, and the pixel counters
                done_until = k + PACKET
                for _ in range(PACKET):
                    sample, col, row = _next_sample(sample, col, row, per_pixel, width)
                    if has_background:
                        for ch in range(3):
                            rgb[row, col, ch] += weight * background[ch]
                continue
        if usable:  # some hit, so first_m ≥ 0
            done_until = k + PACKET
            m = first_m
            if m != last_m:
                last_m = m
                base = _material_row(materials, m)
            material = base
            # Pass A: the hits' rows (a miss reads face 0's, and its lanes are ignored).
            for j in range(PACKET):
                f = max(face[k + j], 0)
                b1, b2 = one * bu[k + j], one * bv[k + j]
                b0 = one - b1 - b2
                gx, gy, gz = face_normals[f, 0], face_normals[f, 1], face_normals[f, 2]
                lane[0, j] = facing_side(gx, gy, gz, directions[k + j, 0], directions[k + j, 1],
                                         directions[k + j, 2], two_sided, one)
                lane[1, j], lane[2, j], lane[3, j] = gx, gy, gz
                lane[4, j], lane[5, j], lane[6, j] = hit_point(vertices, faces, f, b0, b1, b2)
                lane[7, j], lane[8, j], lane[9, j] = _mixed_normal(corner_normals, f, b0, b1, b2)
            # Pass B: normal, view and light vectors, f_att, n·l and the highlight's cosine, lane by lane.
            ex, ey, ez = view[V_EYE], view[V_EYE + 1], view[V_EYE + 2]
            qx, qy, qz = lights[0, L_VEC], lights[0, L_VEC + 1], lights[0, L_VEC + 2]
            c0, c1, c2 = lights[0, L_ATT], lights[0, L_ATT + 1], lights[0, L_ATT + 2]
            floor = view[V_FLOOR]
            for j in range(PACKET):
                side, px, py, pz = lane[0, j], lane[4, j], lane[5, j], lane[6, j]
                sx, sy, sz = lane[7, j], lane[8, j], lane[9, j]
                nx, ny, nz = side * lane[1, j], side * lane[2, j], side * lane[3, j]
                length = math.sqrt(sx * sx + sy * sy + sz * sz)
                if length > one * NO_DIRECTION:
                    nx, ny, nz = side * sx / length, side * sy / length, side * sz / length
                vx, vy, vz = view[V_VIEW], view[V_VIEW + 1], view[V_VIEW + 2]
                if per_point:
                    vx, vy, vz = view_direction(px, py, pz, ex, ey, ez, zero)
                lx, ly, lz, d = to_light(point_light, qx, qy, qz, px, py, pz, nx, ny, nz, floor)
                fall = attenuation(falloff, c0, c1, c2, d, floor, one)
                n_dot_l = nx * lx + ny * ly + nz * lz
                lane[10, j], lane[11, j], lane[12, j] = nx, ny, nz
                lane[13, j] = n_dot_l
                lane[14, j] = zero
                if specular != SPECULAR_NONE:
                    lane[14, j] = highlight_cosine(specular, n_dot_l, nx, ny, nz, lx, ly, lz, vx, vy, vz, zero, two)
                lane[15, j] = fall
            # Pass C: the terms (powf stays scalar) and the film, in ray order.
            for j in range(PACKET):
                sample, col, row = _next_sample(sample, col, row, per_pixel, width)
                f = face[k + j]
                if f < 0:
                    if has_background:
                        for ch in range(3):
                            rgb[row, col, ch] += weight * background[ch]
                    continue
                visible_k = visible[k + j] if shadows else ALL_VISIBLE
                ar = ag = ab = dr = dg = db = sr = sg = sb = er = eg = eb = zero
                mask = fixed
                if flags & F_EMISSION:
                    er, eg, eb = material.ke_r, material.ke_g, material.ke_b
                if flags & F_SCENE_AMBIENT:
                    ar = view[V_AMBIENT] * material.ka_r
                    ag, ab = view[V_AMBIENT + 1] * material.ka_g, view[V_AMBIENT + 2] * material.ka_b
                fall = lane[15, j]
                if flags & F_LIGHT_AMBIENT:
                    ar += fall * lights[0, L_IA] * material.ka_r
                    ag += fall * lights[0, L_IA + 1] * material.ka_g
                    ab += fall * lights[0, L_IA + 2] * material.ka_b
                n_dot_l = lane[13, j]
                if visible_k & 1 != 0 and n_dot_l > zero:
                    if flags & F_DIFFUSE:
                        mask |= 1 << C_DIFFUSE
                        r, g, b = diffuse_terms(fall, n_dot_l, lights[0, L_ID], lights[0, L_ID + 1],
                                                lights[0, L_ID + 2], material, zero, one, two)
                        dr, dg, db = dr + r, dg + g, db + b
                    if specular != SPECULAR_NONE:
                        mask |= 1 << C_SPECULAR
                        r, g, b = specular_terms(fall, lane[14, j], lights[0, L_IS], lights[0, L_IS + 1],
                                                 lights[0, L_IS + 2], material, zero, one)
                        sr, sg, sb = sr + r, sg + g, sb + b
                if mask != run_mask:
                    for bit in range(TERMS):
                        evaluated[bit] += run_length * ((run_mask >> bit) & 1)
                    run_mask, run_length = mask, 0
                run_length += 1
                rgb[row, col, 0] += weight * (ar + dr + sr + er)
                rgb[row, col, 1] += weight * (ag + dg + sg + eg)
                rgb[row, col, 2] += weight * (ab + db + sb + eb)
                if term_layers:
                    for term, (r, g, b) in enumerate(((ar, ag, ab), (dr, dg, db), (sr, sg, sb), (er, eg, eb))):
                        terms[row, col, term, 0] += weight * r
                        terms[row, col, term, 1] += weight * g
                        terms[row, col, term, 2] += weight * b
                if geometry_layers and sample == centre_sample:
                    nx, ny, nz = lane[10, j], lane[11, j], lane[12, j]
                    depth[row, col] = tfar[k + j] * inputs.frame_scale
                    face_out[row, col] = f
                    length = math.sqrt(nx * nx + ny * ny + nz * nz)
                    if length > 0:
                        normal[row, col, 0], normal[row, col, 1], normal[row, col, 2] = (
                            nx / length, ny / length, nz / length)
            continue
        sample, col, row = _next_sample(sample, col, row, per_pixel, width)
        # The face rows (normal, corners, corner normals, vertices) of the hit AHEAD rays on: they are cache
        # misses on a mesh larger than the cache, and one pass per hit is too long for the CPU to run that far.
        if k + AHEAD < face.shape[0]:
            ahead = face[k + AHEAD]
            if ahead >= 0:
                _prefetch(face_normals, 3 * ahead)
                _prefetch(faces, 3 * ahead)
                _prefetch(corner_normals, 9 * ahead)
                _prefetch(vertices, 3 * faces[ahead, 0])
                _prefetch(vertices, 3 * faces[ahead, 1])
                _prefetch(vertices, 3 * faces[ahead, 2])
        f = face[k]
        visible_k = visible[k] if shadows else ALL_VISIBLE
        if f < 0:
            if has_background:
                for ch in range(3):
                    rgb[row, col, ch] += weight * background[ch]
            continue

        i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
        b1, b2 = one * bu[k], one * bv[k]
        b0 = one - b1 - b2
        if screen:
            b0, b1, b2 = _screen_weights(b0, b1, b2, vertices, i0, i1, i2, eye, camera, one)
        gx, gy, gz = face_normals[f, 0], face_normals[f, 1], face_normals[f, 2]
        # Shade the side the viewer sees.
        side = facing_side(gx, gy, gz, directions[k, 0], directions[k, 1], directions[k, 2], two_sided, one)
        m = face_material[f]
        if m != last_m:
            last_m = m
            base = _material_row(materials, m)
        material = base
        model = face_model[f]
        if textured:
            # The sample's world footprint: t × spread across the ray, stretched by 1/|cos θ| on the surface.
            cosine = abs(gx * directions[k, 0] + gy * directions[k, 1] + gz * directions[k, 2])
            footprint = (spread if orthographic else spread * tfar[k] * inputs.frame_scale) / max(cosine, 1e-3)
            material = _textured_material(materials, texels, texture_table, corner_uv, uv_density, material, m, f,
                                          b0, b1, b2, footprint, one, cast)
        if coloured and model != GOURAUD:  # Gouraud lights each corner with its own colour, below
            w0, w1, w2 = (third, third, third) if model == FLAT else (b0, b1, b2)
            material = _modulated(material, w0 * colours[f, 0, 0] + w1 * colours[f, 1, 0] + w2 * colours[f, 2, 0],
                                  w0 * colours[f, 0, 1] + w1 * colours[f, 1, 1] + w2 * colours[f, 2, 1],
                                  w0 * colours[f, 0, 2] + w1 * colours[f, 1, 2] + w2 * colours[f, 2, 2])
        nx, ny, nz = side * gx, side * gy, side * gz
        if model == FLAT:
            px, py, pz = hit_point(vertices, faces, f, third, third, third)  # the centroid
            ar, ag, ab, dr, dg, db, sr, sg, sb, er, eg, eb, mask = illuminate(
                px, py, pz, nx, ny, nz, material, lights, view_tuple, flags, specular, visible_k, zero, one, two)
        elif model == GOURAUD:
            ar = ag = ab = dr = dg = db = sr = sg = sb = er = eg = eb = zero
            mask = 0
            for j in range(3):
                vj = faces[f, j]
                bj = b0 if j == 0 else (b1 if j == 1 else b2)
                corner_material = material
                if coloured:
                    corner_material = _modulated(material, colours[f, j, 0], colours[f, j, 1], colours[f, j, 2])
                lit = illuminate(
                    vertices[vj, 0], vertices[vj, 1], vertices[vj, 2], side * corner_normals[f, j, 0],
                    side * corner_normals[f, j, 1], side * corner_normals[f, j, 2], corner_material, lights,
                    view_tuple, flags, specular, visible_k, zero, one, two)
                ar, ag, ab = ar + bj * lit.ambient_r, ag + bj * lit.ambient_g, ab + bj * lit.ambient_b
                dr, dg, db = dr + bj * lit.diffuse_r, dg + bj * lit.diffuse_g, db + bj * lit.diffuse_b
                sr, sg, sb = sr + bj * lit.specular_r, sg + bj * lit.specular_g, sb + bj * lit.specular_b
                er, eg, eb = er + bj * lit.emission_r, eg + bj * lit.emission_g, eb + bj * lit.emission_b
                mask |= lit.mask
            if geometry_layers:
                sx, sy, sz = _mixed_normal(corner_normals, f, b0, b1, b2)
                nx, ny, nz = side * sx, side * sy, side * sz
        else:
            px, py, pz = hit_point(vertices, faces, f, b0, b1, b2)
            sx, sy, sz = _mixed_normal(corner_normals, f, b0, b1, b2)
            length = math.sqrt(sx * sx + sy * sy + sz * sz)
            # A mix of unit normals with no length points nowhere in particular: keep the face normal.
            if length > one * NO_DIRECTION:
                nx, ny, nz = side * sx / length, side * sy / length, side * sz / length
            ar, ag, ab, dr, dg, db, sr, sg, sb, er, eg, eb, mask = illuminate(
                px, py, pz, nx, ny, nz, material, lights, view_tuple, flags, specular, visible_k, zero, one, two)

        if mask != run_mask:
            for bit in range(TERMS):
                evaluated[bit] += run_length * ((run_mask >> bit) & 1)
            run_mask, run_length = mask, 0
        run_length += 1
        rgb[row, col, 0] += weight * (ar + dr + sr + er)
        rgb[row, col, 1] += weight * (ag + dg + sg + eg)
        rgb[row, col, 2] += weight * (ab + db + sb + eb)
        if term_layers:
            for term, (r, g, b) in enumerate(((ar, ag, ab), (dr, dg, db), (sr, sg, sb), (er, eg, eb))):
                terms[row, col, term, 0] += weight * r
                terms[row, col, term, 1] += weight * g
                terms[row, col, term, 2] += weight * b
        if geometry_layers and sample == centre_sample:
            depth[row, col] = tfar[k] * inputs.frame_scale
            face_out[row, col] = f
            length = math.sqrt(nx * nx + ny * ny + nz * nz)
            if length > 0:
                normal[row, col, 0], normal[row, col, 1], normal[row, col, 2] = nx / length, ny / length, nz / length
    for bit in range(TERMS):
        evaluated[bit] += run_length * ((run_mask >> bit) & 1)
    counts[:] = evaluated
