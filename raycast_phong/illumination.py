"""The illumination model at one surface point, compiled with numba; it knows no rays or meshes.

    I = k_e + I_a k_a + Σ_lights f_att [ I_a,light k_a + I_d k_d max(l·n, 0) + I_s k_s S ]

S = max(v·r, 0)^f with r = 2(l·n)n − l (Phong 1975), or max(n·h, 0)^f with h = normalize(l + v) (Blinn
1977); S = 0 where l·n ≤ 0. f_att is 1, 1/d², or min(1, 1/(c + l·d + q·d²)); 1 for directional lights.
The four terms are kept apart (ambient, diffuse, specular, emission) so they can be written as layers.
All arithmetic happens in the dtype of the arrays passed in (the scene's `precision`): the constants
0, 1, 2 come from the array `c` of that dtype, never from Python literals, which numba would widen.
"""

from __future__ import annotations

import math

from numba import njit

# Indices into the `flags` array (int64) that the render plan fills in.
F_SPECULAR = 0        # 0: no specular work, 1: phong (v·r), 2: blinn (n·h)
F_ATTENUATION = 1     # some point light attenuates
F_LIGHT_AMBIENT = 2   # some light has its own ambient intensity
F_EMISSION = 3        # some material emits
F_SCENE_AMBIENT = 4   # I_a k_a is non-zero somewhere
F_DIFFUSE = 5         # some light and material have a diffuse part
F_VIEW_PER_POINT = 6  # local viewer with a perspective camera: v = normalize(eye − p) per point
F_TWO_SIDED = 7       # flip the shading normal of a back-facing hit toward the viewer
F_SCREEN = 8          # interpolate with screen-space weights instead of perspective-correct ones
F_AOV_GEOMETRY = 9    # write depth, normal and face layers
F_AOV_TERMS = 10      # write the per-term layers
FLAG_COUNT = 11

# Indices into the `counts` array: how many times each optional term was evaluated.
COUNTED_TERMS = ("specular", "attenuation", "light_ambient", "emission", "scene_ambient", "diffuse",
                 "view_vector")
C_SPECULAR, C_ATTENUATION, C_LIGHT_AMBIENT, C_EMISSION, C_SCENE_AMBIENT, C_DIFFUSE, C_VIEW = range(7)

# Layers of the accumulator `acc` (4, 3).
AMBIENT, DIFFUSE, SPECULAR, EMISSION = range(4)


@njit(cache=True, nogil=True)
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


@njit(cache=True, nogil=True)
def illuminate(px, py, pz, nx, ny, nz, m, w, ka, kd, ks, ke, shininess,
               light_kind, light_vec, light_id, light_is, light_ia, light_att_kind, light_att,
               ambient, eye, fixed_view, flags, c, acc, counts):
    """Add w × (the model at point p with unit normal n, material m) to acc[term, channel].

    light_vec holds a point light's position, or a directional light's unit vector toward the light.
    """
    zero, one, two, tiny = c[0], c[1], c[2], c[3]
    if flags[F_EMISSION]:
        counts[C_EMISSION] += 1
        for ch in range(3):
            acc[EMISSION, ch] += w * ke[m, ch]
    if flags[F_SCENE_AMBIENT]:
        counts[C_SCENE_AMBIENT] += 1
        for ch in range(3):
            acc[AMBIENT, ch] += w * ambient[ch] * ka[m, ch]

    specular = flags[F_SPECULAR]
    vx, vy, vz = fixed_view[0], fixed_view[1], fixed_view[2]
    if specular != 0 and flags[F_VIEW_PER_POINT]:
        counts[C_VIEW] += 1
        vx, vy, vz = eye[0] - px, eye[1] - py, eye[2] - pz
        length = math.sqrt(vx * vx + vy * vy + vz * vz)
        if length > zero:
            vx, vy, vz = vx / length, vy / length, vz / length

    for k in range(light_kind.shape[0]):
        d = zero
        if light_kind[k] == 0:
            lx, ly, lz = light_vec[k, 0] - px, light_vec[k, 1] - py, light_vec[k, 2] - pz
            d = math.sqrt(lx * lx + ly * ly + lz * lz)
            if d > zero:
                lx, ly, lz = lx / d, ly / d, lz / d
            else:
                # A light exactly on the surface has no direction: treat it as head-on.
                lx, ly, lz = nx, ny, nz
        else:
            lx, ly, lz = light_vec[k, 0], light_vec[k, 1], light_vec[k, 2]

        weight = w
        if flags[F_ATTENUATION] and light_att_kind[k] != 0:
            counts[C_ATTENUATION] += 1
            if light_att_kind[k] == 1:
                # 1/d² exactly; d² is floored at the smallest normal number so d = 0 stays finite.
                weight = w * (one / max(d * d, tiny))
            else:
                weight = w * min(one, one / (light_att[k, 0] + light_att[k, 1] * d + light_att[k, 2] * d * d))

        if flags[F_LIGHT_AMBIENT]:
            counts[C_LIGHT_AMBIENT] += 1
            for ch in range(3):
                acc[AMBIENT, ch] += weight * light_ia[k, ch] * ka[m, ch]

        n_dot_l = nx * lx + ny * ly + nz * lz
        if n_dot_l <= zero:
            continue  # no diffuse and no highlight on a side turned away from the light
        if flags[F_DIFFUSE]:
            counts[C_DIFFUSE] += 1
            for ch in range(3):
                acc[DIFFUSE, ch] += weight * light_id[k, ch] * kd[m, ch] * n_dot_l
        if specular != 0:
            counts[C_SPECULAR] += 1
            if specular == 1:
                rx, ry, rz = two * n_dot_l * nx - lx, two * n_dot_l * ny - ly, two * n_dot_l * nz - lz
                x = rx * vx + ry * vy + rz * vz
            else:
                hx, hy, hz = lx + vx, ly + vy, lz + vz
                length = math.sqrt(hx * hx + hy * hy + hz * hz)
                x = (nx * hx + ny * hy + nz * hz) / length if length > zero else zero
            s = specular_power(x, shininess[m], zero, one)
            if s > zero:
                for ch in range(3):
                    acc[SPECULAR, ch] += weight * light_is[k, ch] * ks[m, ch] * s
