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

import numpy as np

from .jit import kernel
from .surface import to_light

# Bits of the `flags` integer that the render plan fills in (the specular model travels apart).
F_ATTENUATION = 1 << 0     # some point light attenuates
F_LIGHT_AMBIENT = 1 << 1   # some light has its own ambient intensity
F_EMISSION = 1 << 2        # some material emits
F_SCENE_AMBIENT = 1 << 3   # I_a k_a is non-zero somewhere
F_DIFFUSE = 1 << 4         # some light and material have a diffuse part
F_VIEW_PER_POINT = 1 << 5  # local viewer with a perspective camera: v = normalize(eye − p) per point
F_TWO_SIDED = 1 << 6       # flip the shading normal of a back-facing hit toward the viewer
F_SCREEN = 1 << 7          # interpolate with screen-space weights instead of perspective-correct ones
F_AOV_GEOMETRY = 1 << 8    # write depth, normal and face layers
F_AOV_TERMS = 1 << 9       # write the per-term layers
F_SHADOWS = 1 << 10        # global mode: per-ray light visibility masks are given
SPECULAR_NONE, SPECULAR_PHONG, SPECULAR_BLINN = 0, 1, 2

# Columns of the material table (M, 13) and of the light table (K, 17); material_table and light_table
# below are the only writers, illuminate the only reader.
KA, KD, KS, KE, SHININESS, MATERIAL_COLUMNS = 0, 3, 6, 9, 12, 13
L_KIND, L_VEC, L_ID, L_IS, L_IA, L_ATT_KIND, L_ATT, LIGHT_COLUMNS = 0, 1, 4, 7, 10, 13, 14, 17
POINT, DIRECTIONAL = 0, 1                                    # L_KIND
ATTENUATION_NONE, INVERSE_SQUARE, CLQ = 0, 1, 2              # L_ATT_KIND

# Indices into the `counts` array: how many times each optional term was evaluated.
COUNTED_TERMS = ("specular", "attenuation", "light_ambient", "emission", "scene_ambient", "diffuse",
                 "view_vector")
C_SPECULAR, C_ATTENUATION, C_LIGHT_AMBIENT, C_EMISSION, C_SCENE_AMBIENT, C_DIFFUSE, C_VIEW = range(7)
TERMS = len(COUNTED_TERMS)
# The tile kernel's counts: the terms, then the shadow rays it cast (global mode's stage, counted where it runs).
COUNTS = (*COUNTED_TERMS, "shadow_rays")
C_SHADOW_RAYS = TERMS


def material_table(materials, real: type, more: np.ndarray | None = None) -> np.ndarray:
    """(M, MATERIAL_COLUMNS) array of `real`: per material k_a, k_d, k_s, k_e (r, g, b each) and f; then the
    rows `more` (material_rows: the materials read from mesh files)."""
    table = material_rows(*(np.array([getattr(m, key) for m in materials], np.float64).reshape(len(materials), -1)
                            for key in ("ka", "kd", "ks", "ke", "shininess")))
    if more is not None:
        table = np.concatenate([table, more])
    return np.ascontiguousarray(table, real)


def material_rows(ka, kd, ks, ke, shininess) -> np.ndarray:
    """(M, MATERIAL_COLUMNS) float64 rows of the material table from (M, 3) coefficients and (M,) or (M, 1) f."""
    table = np.zeros((len(ka), MATERIAL_COLUMNS))
    table[:, KA:KA + 3], table[:, KD:KD + 3], table[:, KS:KS + 3], table[:, KE:KE + 3] = ka, kd, ks, ke
    table[:, SHININESS] = np.reshape(shininess, -1)
    return table


def light_table(lights, center: np.ndarray, attenuate: bool, real: type) -> np.ndarray:
    """(K, LIGHT_COLUMNS) array of `real`: per light its kind, a point light's position − `center` or a
    directional light's unit vector toward it, I_d, I_s, I_a, and its attenuation kind with c, l, q.

    f_att = 1 for directional lights, whatever the file says. When some light attenuates (`attenuate`),
    "none" is written as min(1, 1/(1 + 0 d + 0 d²)) = 1, so that every light takes the same branch.
    """
    table = np.zeros((len(lights), LIGHT_COLUMNS))
    for row, light in zip(table, lights):
        if light.type == "point":
            row[L_KIND], row[L_VEC:L_VEC + 3] = POINT, np.asarray(light.position) - center
        else:
            toward = -np.asarray(light.direction, np.float64)
            row[L_KIND], row[L_VEC:L_VEC + 3] = DIRECTIONAL, toward / np.linalg.norm(toward)
        row[L_ID:L_ID + 3], row[L_IS:L_IS + 3], row[L_IA:L_IA + 3] = light.diffuse, light.specular, light.ambient
        if light.type == "directional" or light.attenuation == "none":
            row[L_ATT_KIND], row[L_ATT:L_ATT + 3] = (CLQ if attenuate else ATTENUATION_NONE), (1.0, 0.0, 0.0)
        elif light.attenuation == "inverse_square":
            row[L_ATT_KIND], row[L_ATT:L_ATT + 3] = INVERSE_SQUARE, (0.0, 0.0, 1.0)
        else:
            row[L_ATT_KIND], row[L_ATT:L_ATT + 3] = CLQ, light.attenuation
    return np.ascontiguousarray(table, real)


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
def illuminate(px, py, pz, nx, ny, nz, material, lights, view, flags, specular, visible, zero, one, two):
    """The model at point p with unit normal n and one material (a row of the material table, as a tuple).

    view = (I_a r, g, b, eye x, y, z, fixed view x, y, z, smallest d² of 1/d²), a tuple. `visible` holds one
    bit per light (global mode's shadow-ray answers; all bits set in local mode): a light whose bit is
    clear adds only its ambient part. Returns the four terms as 12 scalars
    (ambient, diffuse, specular, emission; r, g, b each) and a bit mask of the optional terms
    evaluated (bit i = COUNTED_TERMS[i]). Tuples and scalars, and one array: every array argument
    costs an atomic reference count per call, which dominated the frame time of an earlier version.
    A light's L_VEC is a point light's position, or a directional light's unit vector toward it.
    """
    ar = ag = ab = dr = dg = db = sr = sg = sb = er = eg = eb = zero
    mask = 0
    if flags & F_EMISSION:
        mask |= 1 << C_EMISSION
        er, eg, eb = material[KE], material[KE + 1], material[KE + 2]
    ka_r, ka_g, ka_b = material[KA], material[KA + 1], material[KA + 2]
    if flags & F_SCENE_AMBIENT:
        mask |= 1 << C_SCENE_AMBIENT
        ar, ag, ab = view[0] * ka_r, view[1] * ka_g, view[2] * ka_b

    vx, vy, vz = view[6], view[7], view[8]
    if specular != SPECULAR_NONE and flags & F_VIEW_PER_POINT:
        mask |= 1 << C_VIEW
        vx, vy, vz = view[3] - px, view[4] - py, view[5] - pz
        length = math.sqrt(vx * vx + vy * vy + vz * vz)
        if length > zero:
            vx, vy, vz = vx / length, vy / length, vz / length

    for k in range(lights.shape[0]):
        lx, ly, lz, d = to_light(lights[k, L_KIND] == POINT, lights[k, L_VEC], lights[k, L_VEC + 1],
                                 lights[k, L_VEC + 2], px, py, pz, nx, ny, nz, view[9])

        weight = one
        if flags & F_ATTENUATION and lights[k, L_ATT_KIND] != ATTENUATION_NONE:
            mask |= 1 << C_ATTENUATION
            if lights[k, L_ATT_KIND] == INVERSE_SQUARE:
                # 1/d² exactly, with d floored at 1e-6 of the scene's size (view[9] = that floor²), so a
                # light on or inside the surface stays finite in float32 too.
                weight = one / max(d * d, view[9])
            else:
                # min(1, 1/x) as 1/max(1, x): the same for x ≥ 0, and never 1/0 where x = 0 (c = 0 at d = 0).
                weight = one / max(one, lights[k, L_ATT] + lights[k, L_ATT + 1] * d + lights[k, L_ATT + 2] * d * d)

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
            lit = weight * n_dot_l
            dr += lit * lights[k, L_ID] * material[KD]
            dg += lit * lights[k, L_ID + 1] * material[KD + 1]
            db += lit * lights[k, L_ID + 2] * material[KD + 2]
        if specular != SPECULAR_NONE:
            mask |= 1 << C_SPECULAR
            if specular == SPECULAR_PHONG:
                rx, ry, rz = two * n_dot_l * nx - lx, two * n_dot_l * ny - ly, two * n_dot_l * nz - lz
                x = rx * vx + ry * vy + rz * vz
            else:
                hx, hy, hz = lx + vx, ly + vy, lz + vz
                length = math.sqrt(hx * hx + hy * hy + hz * hz)
                x = (nx * hx + ny * hy + nz * hz) / length if length > zero else zero
            s = weight * specular_power(x, material[SHININESS], zero, one)
            sr += s * lights[k, L_IS] * material[KS]
            sg += s * lights[k, L_IS + 1] * material[KS + 1]
            sb += s * lights[k, L_IS + 2] * material[KS + 2]
    return ar, ag, ab, dr, dg, db, sr, sg, sb, er, eg, eb, mask
