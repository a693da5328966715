"""Embree 4's queries inside numba kernels: rtcIntersect16 / rtcOccluded16 on packets of 16 rays.

The queries are declared to numba by *name* (numba.types.ExternalFunction); renderer/embree_library.py binds the
names to the library's addresses with llvmlite's `add_symbol` when it loads the library, before any kernel
is compiled or loaded: the cached machine code links by name, so a warm process loads it without compiling
(a ctypes function pointer would freeze a per-process address into the code and defeat numba's cache).

Layouts follow include/embree4/rtcore_ray.h (Embree 4): RTCRayHit16 is structure-of-arrays, 64-byte
aligned; the valid mask is int32[16] with −1 for an active lane; RTCIntersectArguments and
RTCOccludedArguments are filled here (rtcInitIntersectArguments is an inline function, not a symbol).
"""

from __future__ import annotations

import numpy as np
from numba import types

from ...jit import kernel
from .camera import direction, ortho_origin, screen_y, unit_eye
from .layout import ALPHA, ALPHA_CUTOFF, ALPHA_MAP, BLENDED_ALPHA, F_ALPHA_MASK
from .texture import sample

RTC_RAY_QUERY_FLAG_COHERENT = 1 << 16   # neighbouring pixels: Embree may traverse the packet together
RTC_FEATURE_FLAG_ALL = -1               # 0xffffffff as int32
INVALID_ID = -1                         # RTC_INVALID_GEOMETRY_ID, (unsigned) −1

# RTCRayHit16 as float32 words (rtcore_ray.h): 12 ray fields of 16 lanes, then the hit's.
ORG_X, ORG_Y, ORG_Z, TNEAR, DIR_X, DIR_Y, DIR_Z, TIME, TFAR, MASK, ID, FLAGS = (16 * i for i in range(12))
NG_X, NG_Y, NG_Z, HIT_U, HIT_V, PRIM_ID, GEOM_ID = (16 * i for i in range(12, 19))
# instID[RTC_MAX_INSTANCE_LEVEL_COUNT][16] (and instPrimID if instance arrays are on) follow: the build's
# level count is not visible from outside, so leave room for 16 levels of each (Embree's default is 1).
PACKET_WORDS = GEOM_ID + 16 + 2 * 16 * 16  # a multiple of 16: what follows stays 64-byte aligned
ALIGN_WORDS = 16                        # 64 bytes of float32: room to align the packet
ARGUMENT_WORDS = 10                     # RTC*Arguments: 2 int32, 3 pointers, [float minWidthDistanceFactor]
NO_LIMIT = np.float32(1e37)             # embreex's tfar when none is given; a miss keeps it

# The queries, by the names the kernels link against (bound to the library's addresses in `library()`).
INTERSECT16 = "raycast_phong_rtcIntersect16"
OCCLUDED16 = "raycast_phong_rtcOccluded16"
# Pointers travel as intp: on x86-64 and AArch64 a pointer and a 64-bit integer use the same registers.
rtc_intersect16 = types.ExternalFunction(INTERSECT16, types.void(types.intp, types.intp, types.intp, types.intp))
rtc_occluded16 = types.ExternalFunction(OCCLUDED16, types.void(types.intp, types.intp, types.intp, types.intp))


@kernel()
def _packet():
    """A zeroed RTCRayHit16 (float32 words and an int32 view of the same memory), the valid mask and the
    query arguments (coherent rays, all features), each 64-byte aligned: Embree loads the packet and the
    mask with aligned 16-lane loads (rtcIntersect16's documented alignment; a misaligned mask crashes)."""
    store = np.zeros(PACKET_WORDS + 16 + ARGUMENT_WORDS + ALIGN_WORDS, np.float32)
    start = ((-store.ctypes.data) & 63) >> 2
    words = store[start:start + PACKET_WORDS]
    valid = store[start + PACKET_WORDS:start + PACKET_WORDS + 16].view(np.int32)
    arguments = store[start + PACKET_WORDS + 16:start + PACKET_WORDS + 16 + ARGUMENT_WORDS].view(np.int32)
    arguments[0], arguments[1] = RTC_RAY_QUERY_FLAG_COHERENT, RTC_FEATURE_FLAG_ALL
    ints = words.view(np.int32)
    # The fields Embree reads but never writes are set once here: tnear = time = flags = 0 (zeroed), mask all.
    for lane in range(16):
        ints[MASK + lane] = -1
    return words, ints, valid, arguments


@kernel()
def intersect_rays(scene, origins, directions, row_rays, face, u, v, t):
    """Closest hits of rays (N, 3) float32: face (−1 on a miss), u, v (0 on a miss) and t (NO_LIMIT on a
    miss) (N,) written in place.

    The rays are read as an image of row_rays rays a row and cast in packets of 4 × 4 neighbours (coherent:
    Embree traverses a packet together while its rays agree); row_rays = 4 casts 16 consecutive rays.
    Written out in full: a helper taking the arrays measured 3× slower (numba counts references per call).
    """
    words, ints, valid, arguments = _packet()
    count = origins.shape[0]
    for r0 in range(0, -(-count // row_rays), 4):
        for c0 in range(0, row_rays, 4):
            for lane in range(16):
                # Lane (i, j) of the block is ray (r0 + i, c0 + j); off the image's edge it stays inactive.
                c = c0 + (lane & 3)
                k = (r0 + (lane >> 2)) * row_rays + c
                if c < row_rays and k < count:
                    valid[lane] = -1
                    words[ORG_X + lane], words[ORG_Y + lane], words[ORG_Z + lane] = (
                        origins[k, 0], origins[k, 1], origins[k, 2])
                    words[DIR_X + lane], words[DIR_Y + lane], words[DIR_Z + lane] = (
                        directions[k, 0], directions[k, 1], directions[k, 2])
                else:
                    valid[lane] = 0
                words[TFAR + lane] = NO_LIMIT  # a hit lowers tfar and sets the ids: reset them
                ints[GEOM_ID + lane] = INVALID_ID
                ints[PRIM_ID + lane] = INVALID_ID
            rtc_intersect16(valid.ctypes.data, scene, words.ctypes.data, arguments.ctypes.data)
            for lane in range(16):
                c = c0 + (lane & 3)
                k = (r0 + (lane >> 2)) * row_rays + c
                if c >= row_rays or k >= count:
                    continue
                if ints[GEOM_ID + lane] == INVALID_ID:
                    face[k], u[k], v[k], t[k] = -1, 0, 0, NO_LIMIT
                else:
                    face[k], u[k], v[k] = ints[PRIM_ID + lane], words[HIT_U + lane], words[HIT_V + lane]
                    t[k] = words[TFAR + lane]


@kernel()
def camera_hits(scene, params, screen_x, cell_row, row0, row1, eye, directions, face, u, v, t):
    """Closest hits of the primary rays of image rows [row0, row1) (params: layout.RayParams), generated
    straight into Embree's packets: directions (N, 3) float32 (for shading), face, u, v, t (N,) written as
    intersect_rays writes them, the rays in fill_rows' order and the packets in intersect_rays' 4 × 4 blocks
    of rays. screen_x, cell_row: camera.screen_columns(params), made once per band by the caller. eye: (≥1, 3)
    float32 unit-frame origin of a perspective camera's rays (read only then).

    One pass, no rays array: each lane's direction is computed (camera.direction, the same operations and
    bits as fill_rows) into the packet and the directions array at once.
    """
    words, ints, valid, arguments = _packet()
    orthographic = params.orthographic
    forward, right, up = params.forward, params.right, params.up
    start = far_start(params)
    eye_x, eye_y, eye_z = unit_eye(params)  # float64: the far rays' origins start here
    fx, fy, fz, rx, ry, rz, ux, uy, uz = (forward[0], forward[1], forward[2], right[0], right[1], right[2],
                                          up[0], up[1], up[2])
    row_rays, samples = screen_x.shape[0], params.samples
    rows = row1 - row0
    sy_rows = np.empty(4 * samples)  # screen y of the block's 4 image rows × n cell rows
    lane_x, lane_y = np.zeros(16), np.zeros(16)  # the block's screen positions (0 for an inactive lane)
    if not orthographic and rows > 0:
        for lane in range(16):
            words[ORG_X + lane], words[ORG_Y + lane], words[ORG_Z + lane] = eye[0, 0], eye[0, 1], eye[0, 2]
    ox, oy, oz = np.float32(fx), np.float32(fy), np.float32(fz)
    if orthographic:
        for lane in range(16):
            words[DIR_X + lane], words[DIR_Y + lane], words[DIR_Z + lane] = ox, oy, oz
    for r0 in range(0, rows, 4):
        for i in range(4):
            for b in range(samples):
                sy_rows[i * samples + b] = screen_y(params, row0 + r0 + i, b)
        for c0 in range(0, row_rays, 4):
            # Lane (i, j) of the block is ray (r0 + i, c0 + j); off the image's edge it stays inactive.
            for lane in range(16):
                r, c = r0 + (lane >> 2), c0 + (lane & 3)
                active = c < row_rays and r < rows
                valid[lane] = -1 if active else 0
                lane_x[lane] = screen_x[c] if active else 0.0
                lane_y[lane] = sy_rows[(lane >> 2) * samples + cell_row[c]] if active else 0.0
                words[TFAR + lane] = NO_LIMIT
                ints[GEOM_ID + lane] = INVALID_ID
                ints[PRIM_ID + lane] = INVALID_ID
            # Branch-free over the 16 lanes, so that it runs in vector registers.
            if orthographic:
                for lane in range(16):
                    words[ORG_X + lane] = ortho_origin(params, 0, lane_x[lane], lane_y[lane]) + start * fx
                    words[ORG_Y + lane] = ortho_origin(params, 1, lane_x[lane], lane_y[lane]) + start * fy
                    words[ORG_Z + lane] = ortho_origin(params, 2, lane_x[lane], lane_y[lane]) + start * fz
            else:
                for lane in range(16):
                    dx, dy, dz = direction(fx, fy, fz, rx, ry, rz, ux, uy, uz, lane_x[lane], lane_y[lane])
                    words[DIR_X + lane], words[DIR_Y + lane], words[DIR_Z + lane] = dx, dy, dz
                if start > 0.0:
                    # From a point near the scene on the float64 ray: the float32 direction's angle (6e-8)
                    # over the eye's distance would move the ray by 0.06 scene sizes at 1e6 (far_start).
                    for lane in range(16):
                        dx, dy, dz = direction(fx, fy, fz, rx, ry, rz, ux, uy, uz, lane_x[lane], lane_y[lane])
                        words[ORG_X + lane] = eye_x + start * dx
                        words[ORG_Y + lane] = eye_y + start * dy
                        words[ORG_Z + lane] = eye_z + start * dz
            rtc_intersect16(valid.ctypes.data, scene, words.ctypes.data, arguments.ctypes.data)
            for lane in range(16):
                if valid[lane] == 0:
                    continue
                k = (r0 + (lane >> 2)) * row_rays + c0 + (lane & 3)
                directions[k, 0], directions[k, 1], directions[k, 2] = (
                    words[DIR_X + lane], words[DIR_Y + lane], words[DIR_Z + lane])
                # The hit's write-back is intersect_rays' five lines, repeated on purpose: as an inlined
                # helper (store_hit, taking the arrays) it made this cast 3× slower, 28 -> 84 ms of CPU on
                # ico6 at 1000² (bench_frame.py; docs/performance.md, "The store_hit regression").
                if ints[GEOM_ID + lane] == INVALID_ID:
                    face[k], u[k], v[k], t[k] = -1, 0, 0, NO_LIMIT
                else:
                    face[k], u[k], v[k] = ints[PRIM_ID + lane], words[HIT_U + lane], words[HIT_V + lane]
                    t[k] = words[TFAR + lane] + start if start > 0.0 else words[TFAR + lane]


# A camera this many unit-frame radii from the scene's centre (the scene lies within √3 of it) or farther starts
# its primary rays near the scene: a float32 origin 1e6 scene sizes away rounds to about 0.06 of the scene, so
# Embree, which tests triangles relative to the origin, would merge a sphere's front and back. Nearer cameras
# keep their rays as they are.
FAR_EYE = 4096.0
SCENE_RADIUS = 2.0  # > √3: the unit frame's scene lies inside this sphere about its centre


@kernel(inline="always")
def far_start(params):
    """How far along every primary ray it may start without passing any scene point: 0 for a camera nearer than
    FAR_EYE, else its distance to the scene's bounding sphere (perspective: from the eye; orthographic: from
    the eye's plane along the view)."""
    ex, ey, ez = unit_eye(params)
    if params.orthographic:
        distance = -(ex * params.forward[0] + ey * params.forward[1] + ez * params.forward[2])
    else:
        distance = np.sqrt(ex * ex + ey * ey + ez * ez)
    return distance - SCENE_RADIUS if distance > FAR_EYE else 0.0


MAX_LAYERS = 16       # a ray passes through at most this many cut-away surfaces (leaves behind leaves)
PAST_HIT = 2.0 ** -19  # a ray cast on past a cut-away hit starts this share of its t beyond it (16 float32 ulps)


@kernel(inline="always")
def _coverage_threshold(ray, layer):
    """A number in [0, 1) for a ray sample and the surface layer it reached, spread as if at random (a 64-bit
    mix of the two): a BLEND surface covers the sample when its alpha exceeds it."""
    x = np.uint64(ray) * np.uint64(0x9E3779B97F4A7C15) + np.uint64(layer) * np.uint64(0xD1B54A32D192ED03)
    x ^= x >> np.uint64(31)
    x *= np.uint64(0xBF58476D1CE4E5B9)
    x ^= x >> np.uint64(29)
    return float(x >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@kernel(inline="always")
def _cut_away(k, face, u, v, inputs, ray, layer):
    """Whether hit k lies where its material's alpha cuts the surface away: MASK, alpha (the factor times its map
    at the hit's UV, the finest level) below the cutoff (glTF 2.0 §3.9.4); BLEND, alpha below this sample's
    coverage threshold (`ray`: the sample's number in the image, `layer`: how many surfaces it passed), so a
    surface covers a share alpha of a pixel's samples (screen-door transparency)."""
    f = face[k]
    if f < 0:
        return False
    materials = inputs.materials
    m = inputs.face_material[f]
    cutoff = materials[m, ALPHA_CUTOFF]
    if cutoff < 0 and cutoff != BLENDED_ALPHA:
        return False
    alpha = float(materials[m, ALPHA])
    index = int(materials[m, ALPHA_MAP])
    uvs, table = inputs.corner_uv, inputs.texture_table
    if 0 <= index < table.shape[0] and f < uvs.shape[0]:
        b1, b2 = float(u[k]), float(v[k])
        b0 = 1.0 - b1 - b2
        s = b0 * uvs[f, 0, 0] + b1 * uvs[f, 1, 0] + b2 * uvs[f, 2, 0]
        t = b0 * uvs[f, 0, 1] + b1 * uvs[f, 1, 1] + b2 * uvs[f, 2, 1]
        a, _, _ = sample(inputs.texels, table, index, s, t, 1.0)
        alpha *= a
    if cutoff == BLENDED_ALPHA:
        return alpha <= _coverage_threshold(ray, layer)
    return alpha < cutoff


@kernel()
def no_cut(scene, params, screen_x, cell_row, row0, eye, directions, face, u, v, t, inputs):
    """A scene without alpha masks' stand-in for cut_masked, which render_band never calls then."""
    return


@kernel()
def cut_masked(scene, params, screen_x, cell_row, row0, eye, directions, face, u, v, t, inputs):
    """The primary hits of rows from row0 (camera_hits' arrays) that an alpha mask cuts away, cast on past
    themselves until they reach a surface that is kept, or nothing (at most MAX_LAYERS times): the same rays,
    from the same origins camera_hits gave them (the far start included), with tnear just past the hit."""
    if inputs.flags & F_ALPHA_MASK == 0:
        return
    count = face.shape[0]
    pending = np.empty(count, np.int64)
    waiting = 0
    first_ray = row0 * screen_x.shape[0]  # ray k's number in the image: a sample's own coverage thresholds
    for k in range(count):
        if _cut_away(k, face, u, v, inputs, first_ray + k, 0):
            pending[waiting] = k
            waiting += 1
    if waiting == 0:
        return
    words, ints, valid, arguments = _packet()
    start = far_start(params)
    eye_x, eye_y, eye_z = unit_eye(params)
    forward, right, up = params.forward, params.right, params.up
    row_rays = screen_x.shape[0]
    for layer in range(1, MAX_LAYERS + 1):
        for first in range(0, waiting, 16):
            lanes = min(16, waiting - first)
            for lane in range(16):
                valid[lane] = 0
                if lane >= lanes:
                    continue
                k = pending[first + lane]
                c, r = k % row_rays, k // row_rays
                sx, sy = screen_x[c], screen_y(params, row0 + r, cell_row[c])
                valid[lane] = -1
                if params.orthographic:
                    words[ORG_X + lane] = ortho_origin(params, 0, sx, sy) + start * forward[0]
                    words[ORG_Y + lane] = ortho_origin(params, 1, sx, sy) + start * forward[1]
                    words[ORG_Z + lane] = ortho_origin(params, 2, sx, sy) + start * forward[2]
                elif start > 0.0:
                    dx, dy, dz = direction(forward[0], forward[1], forward[2], right[0], right[1], right[2], up[0],
                                           up[1], up[2], sx, sy)
                    words[ORG_X + lane], words[ORG_Y + lane], words[ORG_Z + lane] = (
                        eye_x + start * dx, eye_y + start * dy, eye_z + start * dz)
                else:
                    words[ORG_X + lane], words[ORG_Y + lane], words[ORG_Z + lane] = eye[0, 0], eye[0, 1], eye[0, 2]
                words[DIR_X + lane], words[DIR_Y + lane], words[DIR_Z + lane] = (
                    directions[k, 0], directions[k, 1], directions[k, 2])
                beyond = t[k] - start if start > 0.0 else t[k]
                words[TNEAR + lane] = beyond * (1.0 + PAST_HIT)
                words[TFAR + lane] = NO_LIMIT
                ints[GEOM_ID + lane] = INVALID_ID
                ints[PRIM_ID + lane] = INVALID_ID
            rtc_intersect16(valid.ctypes.data, scene, words.ctypes.data, arguments.ctypes.data)
            for lane in range(lanes):  # the new hit, or a miss (no face) that leaves the sample to the background
                k = pending[first + lane]
                hit = ints[GEOM_ID + lane] != INVALID_ID
                face[k] = ints[PRIM_ID + lane] if hit else -1
                u[k], v[k] = (words[HIT_U + lane], words[HIT_V + lane]) if hit else (0, 0)
                t[k] = (words[TFAR + lane] + start if start > 0.0 else words[TFAR + lane]) if hit else NO_LIMIT
        kept = 0
        for i in range(waiting):
            k = pending[i]
            if _cut_away(k, face, u, v, inputs, first_ray + k, layer):
                pending[kept] = k
                kept += 1
        waiting = kept
        if waiting == 0:
            return
    for i in range(waiting):  # still cut after MAX_LAYERS surfaces: seen through to the background
        k = pending[i]
        face[k], u[k], v[k], t[k] = -1, 0, 0, NO_LIMIT


@kernel()
def fill_packets(origins, directions, row_rays, packets, valid):
    """Rays (N, 3) float32 into RTCRayHit16 packets (P, PACKET_WORDS) float32, 64-byte aligned, and their
    valid masks (P, 16) int32, in intersect_rays' 4 × 4 blocks: the rays cast_packets casts."""
    count = origins.shape[0]
    ints = packets.view(np.int32)
    p = 0
    for r0 in range(0, -(-count // row_rays), 4):
        for c0 in range(0, row_rays, 4):
            for lane in range(16):
                c = c0 + (lane & 3)
                k = (r0 + (lane >> 2)) * row_rays + c
                ints[p, MASK + lane] = -1
                if c < row_rays and k < count:
                    valid[p, lane] = -1
                    packets[p, ORG_X + lane], packets[p, ORG_Y + lane], packets[p, ORG_Z + lane] = (
                        origins[k, 0], origins[k, 1], origins[k, 2])
                    packets[p, DIR_X + lane], packets[p, DIR_Y + lane], packets[p, DIR_Z + lane] = (
                        directions[k, 0], directions[k, 1], directions[k, 2])
                else:
                    valid[p, lane] = 0
            p += 1


@kernel()
def cast_packets(scene, packets, valid):
    """rtcIntersect16 on each prepared packet in turn, resetting only what a hit changes (tfar, geomID):
    Embree's own cost of casting these rays, the yardstick a frame is measured against."""
    _, _, _, arguments = _packet()
    ints = packets.view(np.int32)
    # Addresses by arithmetic: a row view per packet would cost reference counts the yardstick must not pay.
    base, mask_base, packet_bytes = packets.ctypes.data, valid.ctypes.data, 4 * packets.shape[1]
    for p in range(packets.shape[0]):
        for lane in range(16):
            packets[p, TFAR + lane] = NO_LIMIT
            ints[p, GEOM_ID + lane] = INVALID_ID
        rtc_intersect16(mask_base + 64 * p, scene, base + packet_bytes * p, arguments.ctypes.data)


@kernel()
def occluded_rays(scene, origins, directions, t_max, blocked):
    """blocked[k] = something lies on ray k within [0, t_max[k]], in packets of 16 consecutive rays."""
    words, _, valid, arguments = _packet()
    count = origins.shape[0]
    for first in range(0, count, 16):
        lanes = min(16, count - first)
        for lane in range(16):
            if lane < lanes:
                k = first + lane
                valid[lane] = -1
                words[ORG_X + lane], words[ORG_Y + lane], words[ORG_Z + lane] = (
                    origins[k, 0], origins[k, 1], origins[k, 2])
                words[DIR_X + lane], words[DIR_Y + lane], words[DIR_Z + lane] = (
                    directions[k, 0], directions[k, 1], directions[k, 2])
                words[TFAR + lane] = t_max[k]
            else:
                valid[lane] = 0
        rtc_occluded16(valid.ctypes.data, scene, words.ctypes.data, arguments.ctypes.data)
        # An occluded ray's tfar becomes −inf (rtcOccluded16's documented answer).
        for lane in range(lanes):
            blocked[first + lane] = words[TFAR + lane] < 0
