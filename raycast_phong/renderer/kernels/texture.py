"""A colour map sampled at a hit: wrap, bilinear filtering, and the mip level the pixel's footprint asks for.

A texture is a pyramid in one flat texel array (pack.pack_textures): level 0 at the table's T_OFFSET, then
each level half the size of the one before (box-filtered 2 × 2 means), down to 1 × 1. Texel (x, y) of a
level of width w and height h covers u ∈ [x/w, (x+1)/w], v ∈ [1 − (y+1)/h, 1 − y/h] (row 0 at the top,
v up as OBJ and trimesh count it), so its centre is at ((x + ½)/w, 1 − (y + ½)/h).

Level choice (isotropic trilinear, as OpenGL's GL_LINEAR_MIPMAP_LINEAR): the caller gives the footprint of
one pixel sample in level-0 texels, ρ; the level is λ = log2 ρ clamped to [0, levels − 1], and the two
levels around λ are mixed linearly. ρ comes from a ray differential (shading._shade_rays): the sample's
world footprint t·spread/|cos θ| (orthographic: spread alone) times the face's texels per world length,
sqrt(UV area / world area) × sqrt(w h). Isotropic on purpose: a grazing plane takes the coarser level of
its long axis (blurrier than anisotropic filtering, but never aliased).
"""

from __future__ import annotations

import math

from ...jit import kernel
from .layout import T_HEIGHT, T_LEVELS, T_OFFSET, T_WIDTH, T_WRAP_S, T_WRAP_T, WRAP_CLAMP, WRAP_MIRROR


@kernel(inline="always")
def wrap(i, n, mode):
    """Texel index i (any integer) of a row of n texels under a wrap mode: repeat (i mod n), clamp to the
    edge, or mirror (period 2n, every other copy reversed)."""
    if mode == WRAP_CLAMP:
        return min(max(i, 0), n - 1)
    if mode == WRAP_MIRROR:
        p = i % (2 * n)
        return p if p < n else 2 * n - 1 - p
    return i % n


@kernel(inline="always")
def _bilinear(texels, start, w, h, wrap_s, wrap_t, u, v):
    """The bilinear mix of the 2 × 2 texels around (u, v) on one level that starts at texels[start]."""
    x = u * w - 0.5
    y = (1.0 - v) * h - 0.5
    fx, fy = math.floor(x), math.floor(y)
    ax, ay = x - fx, y - fy
    x0, y0 = int(fx), int(fy)
    xa, xb = wrap(x0, w, wrap_s), wrap(x0 + 1, w, wrap_s)
    ya, yb = wrap(y0, h, wrap_t), wrap(y0 + 1, h, wrap_t)
    r = g = b = 0.0
    for yy, wy in ((ya, 1.0 - ay), (yb, ay)):
        for xx, wx in ((xa, 1.0 - ax), (xb, ax)):
            k = start + yy * w + xx
            weight = wx * wy
            r += weight * texels[k, 0]
            g += weight * texels[k, 1]
            b += weight * texels[k, 2]
    return r, g, b


# Compiled once and called, not inlined: numba's IR inlining of sample (with its bilinear mixes and wraps) into
# the three maps' calls took 18 s of a cold compile's 39 s of CPU; the call costs textured shading 3-9 %.
@kernel()
def sample(texels, table, index, u, v, footprint):
    """Linear RGB of texture `index` at (u, v), for a pixel sample covering `footprint` level-0 texels."""
    w, h, levels = table[index, T_WIDTH], table[index, T_HEIGHT], table[index, T_LEVELS]
    wrap_s, wrap_t = table[index, T_WRAP_S], table[index, T_WRAP_T]
    u, v = float(u), float(v)
    if not (math.isfinite(u) and math.isfinite(v)):
        u = v = 0.0
    level = math.log2(footprint) if footprint > 1.0 else 0.0  # NaN footprint: level 0
    level = min(level, levels - 1.0)
    low = int(level)
    mix = level - low
    start = table[index, T_OFFSET]
    for _ in range(low):  # the levels before `low`
        start += w * h
        w, h = max(1, w // 2), max(1, h // 2)
    r = g = b = 0.0
    for step in range(2):  # level `low`, then (if mix > 0) the next one mixed in: one _bilinear to inline, not two
        if step == 1:
            if not mix > 0.0:
                break
            start += w * h
            w, h = max(1, w // 2), max(1, h // 2)
        r1, g1, b1 = _bilinear(texels, start, w, h, wrap_s, wrap_t, u, v)
        if step == 0:
            r, g, b = r1, g1, b1
        else:
            r, g, b = r + mix * (r1 - r), g + mix * (g1 - g), b + mix * (b1 - b)
    return r, g, b
