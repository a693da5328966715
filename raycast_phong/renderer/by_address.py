"""tile.render_band's largest callees, handed to it by address (jit.callee) instead of linked in: the shading
kernel (shading._shade_rays, one handle per type of shading inputs: precision, maps) and global mode's shadow rays
(shadows.cast_shadows; a scene in local mode gets shadows.no_shadow_rays, so it never compiles them) and alpha masks'
cut (ray_queries.cut_masked; a scene without one gets ray_queries.no_cut). render_band then
compiles without either, the shading kernel beside it in a helper process on a first run (split_compile.py), and
neither's code is generated twice. Without numba's first-class functions (jit.BY_ADDRESS) each handle is the kernel's
dispatcher, linked into render_band."""

from __future__ import annotations

import numpy as np
from numba import typeof, types

from .. import jit
from .kernels import ray_queries, shading, shadows
from .kernels.layout import F_ALPHA_MASK, TileRays

_handles: dict[object, object] = {}


def _handle(key, make):
    """The handle kept under `key`, made by `make()` the first time it is asked."""
    if key not in _handles:
        _handles[key] = make()
    return _handles[key]


def no_rays() -> TileRays:
    """A band of no rays, typed as render_band's slices of its buffers: whole empty arrays (a slice of a
    C-contiguous array along its first axis is C-contiguous)."""
    return TileRays(np.empty(0, np.int32), np.empty(0, np.float32), np.empty(0, np.float32),
                    np.empty(0, np.float32), np.empty((0, 3), np.float32), np.empty(0, np.int64), 1)


def shading_arguments(inputs) -> tuple:
    """(ShadingInputs, TileRays, FilmRows) as render_band passes them to _shade_rays, for a band of no rays
    (`inputs`: a ShadingInputs)."""
    from .film import allocate_film
    from .pack import film_rows
    return inputs, no_rays(), film_rows(allocate_film(2, 2, (), inputs.one.dtype.type).rows(0, 0))


def shader(inputs):
    """The handle render_band calls _shade_rays through, for these shading inputs' types."""
    return _handle(typeof(inputs), lambda: jit.callee(shading._shade_rays, shading_arguments(inputs)))


def shadow_arguments() -> tuple:
    """(scene, ShadowInputs, face, u, v, directions, row_rays, visible) as render_band passes them to
    cast_shadows, for a band of no rays (every ShadowInputs has the types pack.no_shadows gives)."""
    from .pack import no_shadows
    rays = no_rays()
    return 0, no_shadows(), rays.face, rays.u, rays.v, rays.directions, 1, rays.visible


def shadow_caster(global_mode: bool):
    """The handle render_band casts shadow rays through: shadows.cast_shadows in global mode, else
    shadows.no_shadow_rays (render_band calls it only in global mode: a local scene never compiles the other)."""
    kernel = shadows.cast_shadows if global_mode else shadows.no_shadow_rays
    return _handle(global_mode, lambda: jit.callee(kernel, shadow_arguments(), types.int64))


def cutter(params, inputs):
    """The handle render_band casts on past alpha-masked hits through, for these ray parameters and shading inputs:
    ray_queries.cut_masked when a material has a mask (layout.F_ALPHA_MASK), else ray_queries.no_cut (render_band
    calls it only with the flag: a scene without masks never compiles the other)."""
    masked = bool(inputs.flags & F_ALPHA_MASK)

    def make():
        rays = no_rays()
        screen = np.zeros(1), np.zeros(1, np.int64)
        arguments = (0, params, *screen, 0, np.zeros((0, 3), np.float32), rays.directions, rays.face, rays.u, rays.v,
                     rays.t, inputs)
        return jit.callee(ray_queries.cut_masked if masked else ray_queries.no_cut, arguments)
    return _handle(("cut", masked, typeof(inputs)), make)
