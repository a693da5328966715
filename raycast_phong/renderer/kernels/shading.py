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

from ...jit import kernel
from ...tolerances import LIT_ROUNDINGS, NO_DIRECTION
from .illumination import diffuse_terms, light_geometry, specular_terms, view_direction
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
    CORNERS,
    E_COSINE,
    E_FALL,
    E_GX,
    E_GY,
    E_GZ,
    E_N_DOT_L,
    E_NX,
    E_NY,
    E_NZ,
    E_PX,
    E_PY,
    E_PZ,
    E_RENORMALISE,
    E_SIDE,
    E_SX,
    E_SY,
    E_SZ,
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
    LIGHT_LANES,
    PHONG,
    POINT,
    POINT_LANES,
    R_B0,
    R_B1,
    R_B2,
    RAY_LANES,
    SHININESS,
    SPECULAR_NONE,
    TERMS,
    V_AMBIENT,
    V_EYE,
    V_FLOOR,
    V_VIEW,
    Material,
)
from .surface import facing_side, hit_point
from .texture import sample

PACKET = 16  # rays shaded together (_shade_rays): an Embree packet, and 16 float32 lanes fill a zmm register
ALL_VISIBLE = -1  # every bit set: local mode, no light is ever shadowed
# The least |cos θ| between a ray and the face it hits that the texture footprint is stretched by: a sample's world
# footprint grows as 1/|cos θ| toward grazing incidence, and is held at 1/GRAZING_COSINE = 1000× the face-on one
# (θ ≈ 89.94°). A ray in the face's own plane (cos θ = 0) would make it infinite, and on a face whose UVs have no
# area (texels per length 0) inf · 0 = NaN, which the mip level reads as level 0: the sharpest, aliasing level.
GRAZING_COSINE = 1e-3


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


@kernel()
def _textured_material(materials, texels, table, uvs, density, material, m, f, b0, b1, b2, footprint, one, cast):
    """The material at a hit with its colour maps applied: each map sampled at the hit's UV (the corners'
    UVs mixed with the weights b), k_a, k_d and k_e multiplied (texture.py chooses the level from
    `footprint`, the sample's world size, times the face's texels per world length). `cast` (3,) in the
    shading precision: a sample passes through it, so the material keeps the precision of the untextured
    path (numba would widen a float32 Material to float64 for every pixel otherwise).
    A kernel of its own, not inlined: a first compile builds it beside _shade_rays (split_compile.py), which
    takes ~0.9 s of CPU off the shading kernel's own compile, for a call per textured hit."""
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


@kernel(inline="always")
def _unit_normals(points, blocks, zero, one):
    """Pass N: each point's unit normal, side × the held normal, or (Phong) the mixed normal renormalised; a mix of
    unit normals with no length points nowhere in particular, and keeps the face normal. Lane by lane (vectorised)."""
    for block in range(blocks):
        for e in range(PACKET):
            side, sx, sy, sz = (points[block, E_SIDE, e], points[block, E_SX, e], points[block, E_SY, e],
                                points[block, E_SZ, e])
            nx, ny, nz = side * points[block, E_GX, e], side * points[block, E_GY, e], side * points[block, E_GZ, e]
            length = math.sqrt(sx * sx + sy * sy + sz * sz)
            if points[block, E_RENORMALISE, e] != zero and length > one * NO_DIRECTION:
                nx, ny, nz = side * sx / length, side * sy / length, side * sz / length
            points[block, E_NX, e], points[block, E_NY, e], points[block, E_NZ, e] = nx, ny, nz


@kernel(inline="always")
def _light_geometry(points, per_light, blocks, lights, n_lights, view, per_point, flags, specular, ex, ey, ez, floor,
                    zero, one, two):
    """Pass B: per light, each point's f_att, n·l and highlight cosine (illumination.light_geometry), lane by lane
    (vectorised); the viewer's direction per point where the highlight needs it (`per_point`), else the view's."""
    for i in range(n_lights):
        point_light = lights[i, L_KIND] == POINT
        qx, qy, qz = lights[i, L_VEC], lights[i, L_VEC + 1], lights[i, L_VEC + 2]
        falloff = lights[i, L_ATT_KIND] if flags & F_ATTENUATION else ATTENUATION_NONE
        c0, c1, c2 = lights[i, L_ATT], lights[i, L_ATT + 1], lights[i, L_ATT + 2]
        for block in range(blocks):
            for e in range(PACKET):
                px, py, pz = points[block, E_PX, e], points[block, E_PY, e], points[block, E_PZ, e]
                nx, ny, nz = points[block, E_NX, e], points[block, E_NY, e], points[block, E_NZ, e]
                vx, vy, vz = view[V_VIEW], view[V_VIEW + 1], view[V_VIEW + 2]
                if per_point:
                    vx, vy, vz = view_direction(px, py, pz, ex, ey, ez, zero)
                fall, n_dot_l, cosine = light_geometry(point_light, qx, qy, qz, falloff, c0, c1, c2, px, py, pz, nx, ny,
                                                       nz, vx, vy, vz, floor, specular, zero, one, two)
                per_light[i, block, E_FALL, e] = fall
                per_light[i, block, E_N_DOT_L, e] = n_dot_l
                per_light[i, block, E_COSINE, e] = cosine


@kernel(inline="always")
def _light_terms(fall, n_dot_l, cosine, visible, ia_r, ia_g, ia_b, id_r, id_g, id_b, is_r, is_g, is_b, lit, flags,
                 specular, zero, one, unlit):
    """One light's part of the model at a point, r, g, b each: f_att I_a k_a whether or not the light reaches it;
    where it does (`visible`: not in shadow, and l·n > `unlit`, LIT_ROUNDINGS units of rounding: a light in the
    surface's plane lights nothing), f_att I_d k_d (l·n) and f_att I_s k_s S; a term not
    evaluated is +0, which leaves a sum as it was (the sums start at +0). With the evaluated terms as layout's C_*
    bits."""
    ar = ag = ab = dr = dg = db = sr = sg = sb = zero
    mask = 0
    if flags & F_LIGHT_AMBIENT:
        ar, ag, ab = fall * ia_r * lit.ka_r, fall * ia_g * lit.ka_g, fall * ia_b * lit.ka_b
    if visible and n_dot_l > unlit:  # no diffuse and no highlight on a side turned away from the light
        if flags & F_DIFFUSE:
            mask |= 1 << C_DIFFUSE
            dr, dg, db = diffuse_terms(fall, n_dot_l, id_r, id_g, id_b, lit)
        if specular != SPECULAR_NONE:
            mask |= 1 << C_SPECULAR
            sr, sg, sb = specular_terms(fall, cosine, is_r, is_g, is_b, lit, zero, one)
    return ar, ag, ab, dr, dg, db, sr, sg, sb, mask


@kernel()
def _shade_rays(inputs, rays, film):
    """Shade every ray of a tile into the film rows (ShadingInputs, TileRays, FilmRows): one engine for every scene.

    PACKET rays at a time, in four passes over named lanes (layout's E_*, R_* rows):
      A  (here) each hit's weights and evaluation points: flat, the centroid; Phong, the hit point and its mixed
         normal; Gouraud, the three corners (ray j's corner c in lane j of block c, so sixteen flat or Phong hits
         are one block);
      N  _unit_normals: each point's unit normal;
      B  _light_geometry: each point and light's f_att, n·l and highlight cosine (N and B lane by lane, which LLVM
         vectorises: vsqrtps, vdivps on zmm);
      C  (here) in ray order: the material (textures and vertex colours applied), each light's terms
         (_light_terms, the one helper for one light and many; libm's powf stays scalar), a Gouraud hit's mix of its
         corners, the run counting and the film, each written once.
    With one light and no vertex colours, a flat or Phong hit skips the corner and light loops and reads the light's
    values once per tile (through the loops, ~45 live values, default Phong shading was 15–35 % slower). Every
    point gets the model's operations in the order of a point shaded alone (k_e, I_a k_a, then each light's ambient,
    diffuse and specular parts; a Gouraud hit 0 + b0 I0 + b1 I1 + b2 I2). Sixteen misses only add the background.
    Arrays come out of their tuples once, here, and passes A and C stay in this body: each array handed to a helper
    costs a reference count per call (pass A as a helper of 13 arrays: shading 8–15 % slower), as does a row view
    such as directions[k] (the frame was 15–28 % slower until the scalars were passed).
    """
    vertices, faces, face_normals = inputs.vertices, inputs.faces, inputs.face_normals
    corner_normals, face_material, face_model = inputs.corner_normals, inputs.face_material, inputs.face_model
    materials, lights, view = inputs.materials, inputs.lights, inputs.viewing
    camera, background = inputs.camera, inputs.background
    flags, specular, zero, one, two = inputs.flags, inputs.specular, inputs.zero, inputs.one, inputs.two
    unlit = zero  # n·l of rounding alone (tolerances.LIT_ROUNDINGS), in the shading's own type (sums, not a product:
    for _ in range(LIT_ROUNDINGS):  # float32 × int is float64 in numba)
        unlit += one - np.nextafter(one, zero)
    face, bu, bv, tfar, directions, visible, samples = rays
    rgb, terms, depth, normal, face_out, counts = film
    width = rgb.shape[1]
    eye = view[V_EYE:V_EYE + 3]
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
    n_lights = lights.shape[0]
    # The lanes: point (c, j) is corner c of ray j, lane j of block c (a flat or Phong hit has only c = 0), so a
    # block with no Gouraud hit is one block of PACKET lanes (zeros or a previous block's values where a ray missed:
    # a pass over a whole block reads them harmlessly). The lane loops count 0..PACKET-1, which LLVM vectorises.
    points = np.zeros((CORNERS, POINT_LANES, PACKET), vertices.dtype)
    per_light = np.zeros((max(n_lights, 1), CORNERS, LIGHT_LANES, PACKET), vertices.dtype)
    weights = np.zeros((RAY_LANES, PACKET), vertices.dtype)
    # Whether the viewer is per point (only the highlight reads v), and the terms every hit evaluates.
    per_point = specular != SPECULAR_NONE and flags & F_VIEW_PER_POINT != 0
    fixed = 0
    if flags & F_EMISSION:
        fixed |= 1 << C_EMISSION
    if flags & F_SCENE_AMBIENT:
        fixed |= 1 << C_SCENE_AMBIENT
    if per_point:
        fixed |= 1 << C_VIEW
    for i in range(n_lights):
        if flags & F_ATTENUATION and lights[i, L_ATT_KIND] != ATTENUATION_NONE:
            fixed |= 1 << C_ATTENUATION
        if flags & F_LIGHT_AMBIENT:
            fixed |= 1 << C_LIGHT_AMBIENT
    ex, ey, ez = view[V_EYE], view[V_EYE + 1], view[V_EYE + 2]
    floor = view[V_FLOOR]
    # One light and no vertex colours (the default scene): a flat or Phong hit is one point lit by one light, shaded
    # in pass C by straight-line code with the light's and the viewing row's values read once, here.
    one_light = n_lights == 1 and not coloured
    ambient_r, ambient_g, ambient_b = view[V_AMBIENT], view[V_AMBIENT + 1], view[V_AMBIENT + 2]
    ia_r = ia_g = ia_b = id_r = id_g = id_b = is_r = is_g = is_b = zero
    if n_lights > 0:
        ia_r, ia_g, ia_b = lights[0, L_IA], lights[0, L_IA + 1], lights[0, L_IA + 2]
        id_r, id_g, id_b = lights[0, L_ID], lights[0, L_ID + 1], lights[0, L_ID + 2]
        is_r, is_g, is_b = lights[0, L_IS], lights[0, L_IS + 1], lights[0, L_IS + 2]
    for k in range(0, face.shape[0], PACKET):
        n = min(PACKET, face.shape[0] - k)
        missed = True
        for j in range(n):
            if face[k + j] >= 0:
                missed = False
                break
        if missed:  # sixteen misses (most of ico6's misses): the background at most, and the pixel counters
            for _ in range(n):
                sample, col, row = _next_sample(sample, col, row, per_pixel, width)
                if has_background:
                    for ch in range(3):
                        rgb[row, col, ch] += weight * background[ch]
            continue
        # Pass A: each hit's weights and evaluation points, in ray order.
        blocks = 1  # CORNERS if some hit is Gouraud
        for j in range(n):
            f = face[k + j]
            if f < 0:
                continue
            b1, b2 = one * bu[k + j], one * bv[k + j]
            b0 = one - b1 - b2
            if screen:
                b0, b1, b2 = _screen_weights(b0, b1, b2, vertices, faces[f, 0], faces[f, 1], faces[f, 2], eye, camera,
                                             one)
            weights[R_B0, j], weights[R_B1, j], weights[R_B2, j] = b0, b1, b2
            gx, gy, gz = face_normals[f, 0], face_normals[f, 1], face_normals[f, 2]
            # Shade the side the viewer sees.
            side = facing_side(gx, gy, gz, directions[k + j, 0], directions[k + j, 1], directions[k + j, 2],
                               two_sided, one)
            model = face_model[f]
            if model == GOURAUD:  # the corners, with their vertex normals
                blocks = CORNERS
                for c in range(CORNERS):
                    v = faces[f, c]
                    points[c, E_SIDE, j] = side
                    points[c, E_GX, j] = corner_normals[f, c, 0]
                    points[c, E_GY, j] = corner_normals[f, c, 1]
                    points[c, E_GZ, j] = corner_normals[f, c, 2]
                    points[c, E_PX, j] = vertices[v, 0]
                    points[c, E_PY, j] = vertices[v, 1]
                    points[c, E_PZ, j] = vertices[v, 2]
                    points[c, E_SX, j] = points[c, E_SY, j] = points[c, E_SZ, j] = zero
                    points[c, E_RENORMALISE, j] = zero
                continue
            w0, w1, w2 = (third, third, third) if model == FLAT else (b0, b1, b2)  # flat: the centroid
            px, py, pz = hit_point(vertices, faces, f, w0, w1, w2)
            sx = sy = sz = renormalise = zero
            if model == PHONG:
                sx, sy, sz = _mixed_normal(corner_normals, f, b0, b1, b2)
                renormalise = one
            points[0, E_SIDE, j] = side
            points[0, E_GX, j], points[0, E_GY, j], points[0, E_GZ, j] = gx, gy, gz
            points[0, E_PX, j], points[0, E_PY, j], points[0, E_PZ, j] = px, py, pz
            points[0, E_SX, j], points[0, E_SY, j], points[0, E_SZ, j] = sx, sy, sz
            points[0, E_RENORMALISE, j] = renormalise
        _unit_normals(points, blocks, zero, one)  # pass N
        _light_geometry(points, per_light, blocks, lights, n_lights, view, per_point, flags, specular, ex, ey, ez,
                        floor, zero, one, two)  # pass B
        # Pass C: in ray order, the material, the terms light by light, the corners' mix, the counts and the film.
        for j in range(n):
            sample, col, row = _next_sample(sample, col, row, per_pixel, width)
            f = face[k + j]
            if f < 0:
                if has_background:
                    for ch in range(3):
                        rgb[row, col, ch] += weight * background[ch]
                continue
            visible_k = visible[k + j] if shadows else ALL_VISIBLE
            b0, b1, b2 = weights[R_B0, j], weights[R_B1, j], weights[R_B2, j]
            m = face_material[f]
            if m != last_m:
                last_m = m
                base = _material_row(materials, m)
            material = base
            model = face_model[f]
            if textured:
                # The sample's world footprint: t × spread across the ray, stretched by 1/|cos θ| on the surface.
                cosine = abs(face_normals[f, 0] * directions[k + j, 0] + face_normals[f, 1] * directions[k + j, 1]
                             + face_normals[f, 2] * directions[k + j, 2])
                world = spread if orthographic else spread * tfar[k + j] * inputs.frame_scale
                footprint = world / max(cosine, GRAZING_COSINE)
                material = _textured_material(materials, texels, texture_table, corner_uv, uv_density, material, m, f,
                                              b0, b1, b2, footprint, one, cast)
            gouraud = model == GOURAUD
            ar = ag = ab = dr = dg = db = sr = sg = sb = er = eg = eb = zero
            mask = fixed
            if one_light and not gouraud:  # one point, one light: the light's values read once a tile, no loops
                if flags & F_EMISSION:
                    er, eg, eb = material.ke_r, material.ke_g, material.ke_b
                if flags & F_SCENE_AMBIENT:
                    ar, ag, ab = ambient_r * material.ka_r, ambient_g * material.ka_g, ambient_b * material.ka_b
                la_r, la_g, la_b, ld_r, ld_g, ld_b, ls_r, ls_g, ls_b, bits = _light_terms(
                    per_light[0, 0, E_FALL, j], per_light[0, 0, E_N_DOT_L, j], per_light[0, 0, E_COSINE, j],
                    visible_k & 1 != 0, ia_r, ia_g, ia_b, id_r, id_g, id_b, is_r, is_g, is_b, material, flags,
                    specular, zero, one, unlit)
                ar, ag, ab, dr, dg, db = ar + la_r, ag + la_g, ab + la_b, dr + ld_r, dg + ld_g, db + ld_b
                sr, sg, sb, mask = sr + ls_r, sg + ls_g, sb + ls_b, mask | bits
            for c in range(0 if one_light and not gouraud else (CORNERS if gouraud else 1)):
                block, e = c, j
                lit = material
                if coloured:  # Gouraud lights each corner with its own colour, flat the mean of its corners
                    if gouraud:
                        r, g, b = colours[f, c, 0], colours[f, c, 1], colours[f, c, 2]
                    else:
                        w0, w1, w2 = (third, third, third) if model == FLAT else (b0, b1, b2)
                        r = w0 * colours[f, 0, 0] + w1 * colours[f, 1, 0] + w2 * colours[f, 2, 0]
                        g = w0 * colours[f, 0, 1] + w1 * colours[f, 1, 1] + w2 * colours[f, 2, 1]
                        b = w0 * colours[f, 0, 2] + w1 * colours[f, 1, 2] + w2 * colours[f, 2, 2]
                    lit = _modulated(material, r, g, b)
                # The model at point e: k_e, I_a k_a, then each light's ambient, diffuse and specular parts.
                pa_r = pa_g = pa_b = pd_r = pd_g = pd_b = ps_r = ps_g = ps_b = pe_r = pe_g = pe_b = zero
                if flags & F_EMISSION:
                    pe_r, pe_g, pe_b = lit.ke_r, lit.ke_g, lit.ke_b
                if flags & F_SCENE_AMBIENT:
                    pa_r, pa_g, pa_b = view[V_AMBIENT] * lit.ka_r, view[V_AMBIENT + 1] * lit.ka_g, view[
                        V_AMBIENT + 2] * lit.ka_b
                for i in range(n_lights):  # in shadow (vis = 0) the direct terms go, the light's ambient stays
                    la_r, la_g, la_b, ld_r, ld_g, ld_b, ls_r, ls_g, ls_b, bits = _light_terms(
                        per_light[i, block, E_FALL, e], per_light[i, block, E_N_DOT_L, e],
                        per_light[i, block, E_COSINE, e], (visible_k >> i) & 1 != 0, lights[i, L_IA],
                        lights[i, L_IA + 1], lights[i, L_IA + 2], lights[i, L_ID], lights[i, L_ID + 1],
                        lights[i, L_ID + 2], lights[i, L_IS], lights[i, L_IS + 1], lights[i, L_IS + 2], lit, flags,
                        specular, zero, one, unlit)
                    pa_r, pa_g, pa_b, pd_r, pd_g, pd_b = (pa_r + la_r, pa_g + la_g, pa_b + la_b, pd_r + ld_r,
                                                          pd_g + ld_g, pd_b + ld_b)
                    ps_r, ps_g, ps_b, mask = ps_r + ls_r, ps_g + ls_g, ps_b + ls_b, mask | bits
                if gouraud:  # 0 + b0 I0 + b1 I1 + b2 I2
                    bc = b0 if c == 0 else (b1 if c == 1 else b2)
                    ar, ag, ab = ar + bc * pa_r, ag + bc * pa_g, ab + bc * pa_b
                    dr, dg, db = dr + bc * pd_r, dg + bc * pd_g, db + bc * pd_b
                    sr, sg, sb = sr + bc * ps_r, sg + bc * ps_g, sb + bc * ps_b
                    er, eg, eb = er + bc * pe_r, eg + bc * pe_g, eb + bc * pe_b
                else:
                    ar, ag, ab, dr, dg, db = pa_r, pa_g, pa_b, pd_r, pd_g, pd_b
                    sr, sg, sb, er, eg, eb = ps_r, ps_g, ps_b, pe_r, pe_g, pe_b
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
                side = points[0, E_SIDE, j]
                nx, ny, nz = points[0, E_NX, j], points[0, E_NY, j], points[0, E_NZ, j]
                if gouraud:
                    sx, sy, sz = _mixed_normal(corner_normals, f, b0, b1, b2)
                    nx, ny, nz = side * sx, side * sy, side * sz
                depth[row, col] = tfar[k + j] * inputs.frame_scale
                face_out[row, col] = f
                length = math.sqrt(nx * nx + ny * ny + nz * nz)
                if length > 0:
                    normal[row, col, 0], normal[row, col, 1], normal[row, col, 2] = (
                        nx / length, ny / length, nz / length)
    for bit in range(TERMS):
        evaluated[bit] += run_length * ((run_mask >> bit) & 1)
    for bit in range(len(counts)):  # not counts[:] = evaluated: its shape check's message compiled in 2 s of 18
        counts[bit] = evaluated[bit]
