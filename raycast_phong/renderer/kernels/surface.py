"""A hit on its triangle, as the shading and the shadow-ray kernels both see it: one home for each rule.

    p = b0 v0 + b1 v1 + b2 v2                       the hit point from its barycentric weights
    side = −1 if two-sided and g · d > 0, else 1    the side of the face the ray sees (g face normal)
    l = normalize(light − p), or the stored unit vector toward a directional light; l = n within the
        distance floor (tolerances.MIN_DISTANCE), where the hit point's rounding would decide l

Inlined into the kernels (numba compiles them in), in whatever precision the arrays passed have.
"""

from __future__ import annotations

import math

from ...jit import kernel


@kernel(inline="always")
def hit_point(vertices, faces, f, b0, b1, b2):
    """b0 v0 + b1 v1 + b2 v2 for face f: the point on the triangle the weights name."""
    i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
    return (b0 * vertices[i0, 0] + b1 * vertices[i1, 0] + b2 * vertices[i2, 0],
            b0 * vertices[i0, 1] + b1 * vertices[i1, 1] + b2 * vertices[i2, 1],
            b0 * vertices[i0, 2] + b1 * vertices[i1, 2] + b2 * vertices[i2, 2])


@kernel(inline="always")
def facing_side(gx, gy, gz, dx, dy, dz, two_sided, one):
    """−1 where a two-sided face is seen from behind (g · d > 0): its normals are flipped toward the ray.

    Scalars, not the ray's row of the directions array: a row view per hit costs an allocation.
    """
    if two_sided and gx * dx + gy * dy + gz * dz > 0:
        return -one
    return one


@kernel(inline="always")
def to_light(point_light, lx, ly, lz, px, py, pz, nx, ny, nz, floor_squared):
    """Unit direction from p toward a light and the distance d (0 for a directional light).

    (lx, ly, lz) is a point light's position or a directional light's unit vector toward it. A point
    light closer than the floor (d² ≤ floor_squared) is head-on, l = n: its true direction would be
    decided by the rounding of p.
    """
    if not point_light:
        return lx, ly, lz, lx - lx  # 0 in lx's precision (a literal 0 would widen float32 to float64)
    dx, dy, dz = lx - px, ly - py, lz - pz
    d2 = dx * dx + dy * dy + dz * dz
    d = math.sqrt(d2)
    if d2 > floor_squared:
        return dx / d, dy / d, dz / d, d
    return nx, ny, nz, d
