"""The illumination model at one surface point, compiled with numba; it knows no rays or meshes.

    I = k_e + I_a k_a + Σ_lights f_att [ I_a,light k_a + I_d k_d max(l·n, 0) + I_s k_s S ]

S = max(v·r, 0)^f with r = 2(l·n)n − l (Phong 1975), or max(n·h, 0)^f with h = normalize(l + v) (Blinn
1977); S = 0 where l·n ≤ 0. f_att is 1, 1/d², or min(1, 1/(c + l·d + q·d²)); 1 for directional lights.
The four terms are kept apart (ambient, diffuse, specular, emission) so they can be written as layers.
All arithmetic happens in the dtype of the arrays passed in (the scene's `precision`): the constants
0, 1, 2 arrive as scalars of that dtype (zero, one, two), never as Python literals, which numba would widen.
"""

from __future__ import annotations

import math

from ...jit import kernel
from .layout import (
    ATTENUATION_NONE,
    C_ATTENUATION,
    C_DIFFUSE,
    C_EMISSION,
    C_LIGHT_AMBIENT,
    C_SCENE_AMBIENT,
    C_SPECULAR,
    C_VIEW,
    F_ATTENUATION,
    F_DIFFUSE,
    F_EMISSION,
    F_LIGHT_AMBIENT,
    F_SCENE_AMBIENT,
    F_VIEW_PER_POINT,
    INVERSE_SQUARE,
    L_ATT,
    L_ATT_KIND,
    L_IA,
    L_ID,
    L_IS,
    L_KIND,
    L_VEC,
    POINT,
    SPECULAR_NONE,
    SPECULAR_PHONG,
    V_AMBIENT,
    V_EYE,
    V_FLOOR,
    V_VIEW,
    Lit,
)
from .surface import to_light


@kernel()
def specular_power(x, f, zero, one):
    """max(x, 0)^f with the limits the format asks for.

    f = 0 is the f → 0⁺ limit (1 where x > 0, else 0), not 0**0 = 1 everywhere; f = inf keeps only
    the exact mirror direction (x ≥ 1).
    """
    if x <= zero:
        return zero
    if f == zero:
        return one
    if math.isinf(f):
        return one if x >= one else zero
    return x ** f


@kernel(inline="always")
def attenuation(kind, constant, linear, quadratic, d, floor_squared, one):
    """f_att of a light at distance d: 1 (ATTENUATION_NONE), 1/d² (INVERSE_SQUARE) or min(1, 1/(c + l d + q d²)),
    c, l, q = constant, linear, quadratic.

    1/d² exactly, with d floored at 1e-6 of the scene's size (floor_squared = view[V_FLOOR], that floor²), so a
    light on or inside the surface stays finite in float32 too; min(1, 1/x) as 1/max(1, x): the same for x ≥ 0,
    and never 1/0 where x = 0 (c = 0 at d = 0)."""
    if kind == INVERSE_SQUARE:
        return one / max(d * d, floor_squared)
    if kind != ATTENUATION_NONE:
        return one / max(one, constant + linear * d + quadratic * d * d)
    return one


@kernel(inline="always")
def view_direction(px, py, pz, ex, ey, ez, zero):
    """v = normalize(eye − p), the local viewer's direction (left as it is if p is the eye)."""
    vx, vy, vz = ex - px, ey - py, ez - pz
    length = math.sqrt(vx * vx + vy * vy + vz * vz)
    if length > zero:
        return vx / length, vy / length, vz / length
    return vx, vy, vz


@kernel(inline="always")
def highlight_cosine(specular, n_dot_l, nx, ny, nz, lx, ly, lz, vx, vy, vz, zero, two):
    """The specular cosine before the power: v·r with r = 2(l·n)n − l (Phong), or n·h with
    h = normalize(l + v) (Blinn; 0 where l + v has no length)."""
    if specular == SPECULAR_PHONG:
        rx, ry, rz = two * n_dot_l * nx - lx, two * n_dot_l * ny - ly, two * n_dot_l * nz - lz
        return rx * vx + ry * vy + rz * vz
    hx, hy, hz = lx + vx, ly + vy, lz + vz
    length = math.sqrt(hx * hx + hy * hy + hz * hz)
    return (nx * hx + ny * hy + nz * hz) / length if length > zero else zero


@kernel(inline="always")
def diffuse_terms(weight, n_dot_l, ir, ig, ib, material, zero, one, two):
    """f_att I_d k_d (l·n) of one light, r, g, b (l·n > 0); zero, one, two as illuminate's."""
    lit = weight * n_dot_l
    return lit * ir * material.kd_r, lit * ig * material.kd_g, lit * ib * material.kd_b


@kernel(inline="always")
def specular_terms(weight, x, ir, ig, ib, material, zero, one):
    """f_att I_s k_s S of one light, r, g, b, with S = specular_power(x, shininess) (l·n > 0)."""
    s = weight * specular_power(x, material.shininess, zero, one)
    return s * ir * material.ks_r, s * ig * material.ks_g, s * ib * material.ks_b


@kernel(inline="always")
def illuminate(px, py, pz, nx, ny, nz, material, lights, view, flags, specular, visible, zero, one, two):
    """The model at point p with unit normal n and one material (layout.Material: a row of the material table).

    view: ShadingInputs.viewing as a tuple (layout.V_AMBIENT, V_EYE, V_VIEW, V_FLOOR). `visible` holds one
    bit per light (global mode's shadow-ray answers; all bits set in local mode): a light whose bit is
    clear adds only its ambient part. Returns a layout.Lit: the four terms (ambient, diffuse, specular,
    emission; r, g, b each) and a bit mask of the optional terms evaluated (bit i = COUNTED_TERMS[i]).
    Tuples and scalars, and one array: every array argument costs an atomic reference count per call,
    which dominated the frame time of an earlier version.
    A light's L_VEC is a point light's position, or a directional light's unit vector toward it.
    """
    ar = ag = ab = dr = dg = db = sr = sg = sb = er = eg = eb = zero
    mask = 0
    if flags & F_EMISSION:
        mask |= 1 << C_EMISSION
        er, eg, eb = material.ke_r, material.ke_g, material.ke_b
    ka_r, ka_g, ka_b = material.ka_r, material.ka_g, material.ka_b
    if flags & F_SCENE_AMBIENT:
        mask |= 1 << C_SCENE_AMBIENT
        ar, ag, ab = view[V_AMBIENT] * ka_r, view[V_AMBIENT + 1] * ka_g, view[V_AMBIENT + 2] * ka_b

    vx, vy, vz = view[V_VIEW], view[V_VIEW + 1], view[V_VIEW + 2]
    if specular != SPECULAR_NONE and flags & F_VIEW_PER_POINT:
        mask |= 1 << C_VIEW
        vx, vy, vz = view_direction(px, py, pz, view[V_EYE], view[V_EYE + 1], view[V_EYE + 2], zero)

    for k in range(lights.shape[0]):
        lx, ly, lz, d = to_light(lights[k, L_KIND] == POINT, lights[k, L_VEC], lights[k, L_VEC + 1],
                                 lights[k, L_VEC + 2], px, py, pz, nx, ny, nz, view[V_FLOOR])

        weight = one
        if flags & F_ATTENUATION and lights[k, L_ATT_KIND] != ATTENUATION_NONE:
            mask |= 1 << C_ATTENUATION
            weight = attenuation(lights[k, L_ATT_KIND], lights[k, L_ATT], lights[k, L_ATT + 1], lights[k, L_ATT + 2],
                                 d, view[V_FLOOR], one)

        if flags & F_LIGHT_AMBIENT:
            mask |= 1 << C_LIGHT_AMBIENT
            ar += weight * lights[k, L_IA] * ka_r
            ag += weight * lights[k, L_IA + 1] * ka_g
            ab += weight * lights[k, L_IA + 2] * ka_b

        if (visible >> k) & 1 == 0:
            continue  # in shadow: vis = 0 removes the direct term only
        n_dot_l = nx * lx + ny * ly + nz * lz
        if n_dot_l <= zero:
            continue  # no diffuse and no highlight on a side turned away from the light
        if flags & F_DIFFUSE:
            mask |= 1 << C_DIFFUSE
            r, g, b = diffuse_terms(weight, n_dot_l, lights[k, L_ID], lights[k, L_ID + 1], lights[k, L_ID + 2],
                                    material, zero, one, two)
            dr, dg, db = dr + r, dg + g, db + b
        if specular != SPECULAR_NONE:
            mask |= 1 << C_SPECULAR
            x = highlight_cosine(specular, n_dot_l, nx, ny, nz, lx, ly, lz, vx, vy, vz, zero, two)
            r, g, b = specular_terms(weight, x, lights[k, L_IS], lights[k, L_IS + 1], lights[k, L_IS + 2], material,
                                     zero, one)
            sr, sg, sb = sr + r, sg + g, sb + b
    return Lit(ar, ag, ab, dr, dg, db, sr, sg, sb, er, eg, eb, mask)
