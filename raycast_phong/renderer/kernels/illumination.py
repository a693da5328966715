"""The illumination model at one surface point, compiled with numba; it knows no rays or meshes.

    I = k_e + I_a k_a + Σ_lights f_att [ I_a,light k_a + I_d k_d max(l·n, 0) + I_s k_s S ]

S = max(v·r, 0)^f with r = 2(l·n)n − l (Phong 1975), or max(n·h, 0)^f with h = normalize(l + v) (Blinn
1977); S = 0 where l·n ≤ 0. f_att is 1, 1/d², or min(1, 1/(c + l·d + q·d²)); 1 for directional lights.
The four terms are kept apart (ambient, diffuse, specular, emission) so they can be written as layers.
The model is evaluated in two steps, as the shading engine (shading._shade_rays) runs it over its lanes: per
point and light the geometry (`light_geometry`: l, f_att, n·l and the highlight's cosine; vectorised), then per
point, light by light in the lights' order, the terms (`diffuse_terms`, `specular_terms`; libm's power, scalar)
added to k_e and I_a k_a. All arithmetic happens in the dtype of the arrays passed in (the scene's `precision`):
the constants 0, 1, 2 arrive as scalars of that dtype (zero, one, two), never as Python literals, which numba
would widen.
"""

from __future__ import annotations

import math

from ...jit import kernel
from .layout import (
    ATTENUATION_NONE,
    INVERSE_SQUARE,
    SPECULAR_NONE,
    SPECULAR_PHONG,
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
def diffuse_terms(weight, n_dot_l, ir, ig, ib, material):
    """f_att I_d k_d (l·n) of one light, r, g, b (l·n > 0; `weight` is f_att)."""
    lit = weight * n_dot_l
    return lit * ir * material.kd_r, lit * ig * material.kd_g, lit * ib * material.kd_b


@kernel(inline="always")
def specular_terms(weight, x, ir, ig, ib, material, zero, one):
    """f_att I_s k_s S of one light, r, g, b, with S = specular_power(x, shininess) (l·n > 0)."""
    s = weight * specular_power(x, material.shininess, zero, one)
    return s * ir * material.ks_r, s * ig * material.ks_g, s * ib * material.ks_b


@kernel(inline="always")
def light_geometry(point_light, qx, qy, qz, falloff, c0, c1, c2, px, py, pz, nx, ny, nz, vx, vy, vz, floor_squared,
                   specular, zero, one, two):
    """One light seen from point p with unit normal n and viewer direction v: f_att, n·l and the highlight's
    cosine (zero without a highlight). (qx, qy, qz): the light's L_VEC; falloff its L_ATT_KIND, or
    ATTENUATION_NONE where the scene attenuates nothing (f_att = 1); c0, c1, c2 its L_ATT. Scalars only: the
    shading engine calls it lane by lane, and LLVM vectorises the loop (no call, no array)."""
    lx, ly, lz, d = to_light(point_light, qx, qy, qz, px, py, pz, nx, ny, nz, floor_squared)
    fall = attenuation(falloff, c0, c1, c2, d, floor_squared, one)
    n_dot_l = nx * lx + ny * ly + nz * lz
    cosine = zero
    if specular != SPECULAR_NONE:
        cosine = highlight_cosine(specular, n_dot_l, nx, ny, nz, lx, ly, lz, vx, vy, vz, zero, two)
    return fall, n_dot_l, cosine
