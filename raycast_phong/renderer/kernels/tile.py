"""One band of image rows in one compiled loop: rays → Embree packets → [shadow rays] → shading, no Python between.

Each stage keeps its home (ray_queries.camera_hits: rays generated straight into Embree's packets, with camera.py's
formulas; shadows.cast_shadows; shading._shade_rays);
this kernel only runs them in turn on CHUNK_ROWS image rows at a time, so a chunk's rays, hits and shadow
rays stay in the CPU's cache and its buffers are allocated once per band. It needs Embree's C API
(ray_queries.py), the renderer's one engine.
"""

from __future__ import annotations

import sys

import numpy as np
from numba import types

from ...jit import kernel
from .camera import screen_columns
from .layout import C_SHADOW_RAYS, F_ALPHA_MASK, F_SHADOWS, FilmRows, TileRays
from .ray_queries import camera_hits

CHUNK_ROWS = 16  # image rows per pass: 4 rows of Embree's 4 × 4 packets (4: 3-7 % more CPU time, ico6 1000²)
TOUCH_FACES = 1 << 17  # meshes of this many faces or more load the hits' face rows first (_touch): 1.6x less
# shading time on a 1M-face scan; none measurable on ico6's 82k faces, whose rows stay in the cache
# clock_gettime(2) from the C library, linked by name like Embree's functions (numba caches the call).
clock_gettime = types.ExternalFunction("clock_gettime", types.int32(types.int32, types.intp))
# CLOCK_THREAD_CPUTIME_ID (<time.h> on macOS, Linux): the stages' CPU time on the thread that runs them, so
# the split holds on a machine other jobs share (a monotonic clock also counted the time others ran).
THREAD_CPU = 16 if sys.platform == "darwin" else 3


@kernel()
def _now(timespec):
    """Seconds of CPU time of this thread (the stage split of render()'s timings)."""
    clock_gettime(THREAD_CPU, timespec.ctypes.data)
    return timespec[0] + 1e-9 * timespec[1]


@kernel()
def _touch(face, faces, vertices, face_normals, corner_normals, per_face):
    """Load the per-face rows the hits `face` will read (the face's corners and their vertices, its normal, its
    corner normals when they are per face, one more per-face column), and return a sum of them.

    In a mesh larger than the cache, nearly every hit is on a face no earlier hit read: its rows are misses.
    The shading and shadow loops are too long for the CPU to run far ahead, so there the misses come one
    after another; in this short loop many are in flight at once, and the long loops then find the rows in
    the cache. The sum keeps the loads from being optimised away."""
    total = 0.0
    per_corner = corner_normals.shape[0] == faces.shape[0]
    for k in range(face.shape[0]):
        f = face[k]
        if f >= 0:
            total += (vertices[faces[f, 0], 0] + vertices[faces[f, 1], 0] + vertices[faces[f, 2], 0]
                      + face_normals[f, 0] + per_face[f])
            if per_corner:
                total += corner_normals[f, 0, 0] + corner_normals[f, 2, 2]
    return total


@kernel()
def render_band(scene, row0, row1, params, shared_origins, shadows, inputs, film, seconds, shade, cast, cut):
    """Render image rows [row0, row1) into `film` (FilmRows of those rows; its counts are set: the terms
    shading._shade_rays evaluated, and the shadow rays cast). scene: embree_library.EmbreeScene.scene; params:
    camera.RayParams; shared_origins: the RayGenerator's (perspective); shadows: ShadowInputs (read in global
    mode only); inputs: ShadingInputs.
    seconds (3,) float64 gets the time of rays (generation + cast), shadow rays and shading added. shade, cast,
    cut: shading._shade_rays, shadows.cast_shadows and ray_queries.cut_masked (hits an alpha mask cuts away, cast
    on past) by their addresses (by_address.py): called, not linked in, so this kernel compiles without them."""
    row_rays = params.width * params.samples * params.samples
    capacity = min(CHUNK_ROWS, row1 - row0) * row_rays  # a band of one very wide row needs one row's buffers
    directions = np.empty((capacity, 3), np.float32)
    face = np.empty(capacity, np.int32)
    u = np.empty(capacity, np.float32)
    v = np.empty(capacity, np.float32)
    t = np.empty(capacity, np.float32)
    visible = np.zeros(capacity, np.int64)
    rgb, terms, depth, normal, face_out, counts = film
    chunk_counts = np.zeros_like(counts)
    counts[:] = 0
    timespec = np.zeros(2, np.int64)
    screen_x, cell_row = screen_columns(params)
    global_mode = inputs.flags & F_SHADOWS != 0
    touched = 0.0
    for row in range(row0, row1, CHUNK_ROWS):
        end = min(row + CHUNK_ROWS, row1)
        n = (end - row) * row_rays
        start = _now(timespec)
        camera_hits(scene, params, screen_x, cell_row, row, end, shared_origins, directions[:n], face[:n], u[:n],
                    v[:n], t[:n])
        if inputs.flags & F_ALPHA_MASK:  # surfaces an alpha mask cuts away: cast on past them
            cut(scene, params, screen_x, cell_row, row, shared_origins, directions[:n], face[:n], u[:n], v[:n],
                t[:n], inputs)
        traced = _now(timespec)
        if global_mode:
            if shadows.faces.shape[0] >= TOUCH_FACES:
                touched += _touch(face[:n], shadows.faces, shadows.vertices, shadows.face_normals,
                                  shadows.corner_normals, shadows.smooth)
            counts[C_SHADOW_RAYS] += cast(scene, shadows, face[:n], u[:n], v[:n], directions[:n], row_rays,
                                          visible[:n])
        shadowed = _now(timespec)
        if inputs.faces.shape[0] >= TOUCH_FACES:
            touched += _touch(face[:n], inputs.faces, inputs.vertices, inputs.face_normals, inputs.corner_normals,
                              inputs.face_material)
        # Film rows of this chunk, relative to the band; a layer not asked for is empty and stays so.
        a, b = row - row0, end - row0
        shade(inputs, TileRays(face[:n], u[:n], v[:n], t[:n], directions[:n], visible[:n], params.samples),
              FilmRows(rgb[a:b], terms[a:b], depth[a:b], normal[a:b], face_out[a:b], chunk_counts))
        counts += chunk_counts
        done = _now(timespec)
        seconds[0] += traced - start
        seconds[1] += shadowed - traced
        seconds[2] += done - shadowed
    seconds[2] += 0.0 * touched  # a finite sum: adds nothing, but the loads it came from must be made
