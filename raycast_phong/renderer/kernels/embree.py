"""Embree 4's C API, from the library embreex installs: scenes built through ctypes on shared buffers,
queried from numba kernels with rtcIntersect16 / rtcOccluded16 on packets of 16 rays.

The queries are declared to numba by *name* (numba.types.ExternalFunction), and the names are bound to
the library's addresses with llvmlite's `add_symbol` when this module loads the library, before any kernel
is compiled or loaded: the cached machine code links by name, so a warm process loads it without compiling
(a ctypes function pointer would freeze a per-process address into the code and defeat numba's cache).

Layouts follow include/embree4/rtcore_ray.h and rtcore_scene.h (Embree 4): RTCRayHit16 is structure-of-
arrays, 64-byte aligned; the valid mask is int32[16] with −1 for an active lane; RTCIntersectArguments and
RTCOccludedArguments are filled here (rtcInitIntersectArguments is an inline function, not a symbol).
This is the renderer's one engine: embreex's wheels link their own modules against the libembree4 they
carry, so wherever embreex imports, this library loads. If it cannot (a missing file or symbol, or
LIBRARY_VARIABLE naming a file that is not the library), `library()` raises one EmbreeError saying so.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
from functools import lru_cache
from pathlib import Path

import numpy as np
from llvmlite import binding
from numba import types

from .jit import kernel

LIBRARY_VARIABLE = "RAYCAST_PHONG_EMBREE_LIBRARY"  # a path to use instead of embreex's own libembree4

# rtcore_common.h / rtcore_geometry.h / rtcore_buffer.h / rtcore_scene.h / rtcore_device.h constants.
RTC_GEOMETRY_TYPE_TRIANGLE = 0
RTC_BUFFER_TYPE_INDEX, RTC_BUFFER_TYPE_VERTEX = 0, 1
RTC_FORMAT_UINT3, RTC_FORMAT_FLOAT3 = 0x5003, 0x9003
RTC_SCENE_FLAG_ROBUST = 1 << 2          # watertight edges, no cracks between faces (as embreex's robust=True)
RTC_RAY_QUERY_FLAG_COHERENT = 1 << 16   # neighbouring pixels: Embree may traverse the packet together
RTC_FEATURE_FLAG_ALL = -1               # 0xffffffff as int32
INVALID_ID = -1                         # RTC_INVALID_GEOMETRY_ID, (unsigned) −1
ERRORS = {1: "unknown error", 2: "invalid argument", 3: "invalid operation", 4: "out of memory",
          5: "unsupported CPU", 6: "cancelled"}

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


class EmbreeError(RuntimeError):
    """Embree reported an error (an internal error of ours, or the machine's: out of memory)."""


def library_path() -> Path | None:
    """LIBRARY_VARIABLE if set, else the libembree4 that embreex's wheel carries beside its package."""
    if os.environ.get(LIBRARY_VARIABLE):
        return Path(os.environ[LIBRARY_VARIABLE])
    spec = importlib.util.find_spec("embreex")
    if spec is None or not spec.submodule_search_locations:
        return None
    package = Path(next(iter(spec.submodule_search_locations)))
    # Linux wheels (auditwheel) put it in embreex.libs/, macOS (delocate) in embreex/.dylibs/.
    found = sorted([*package.parent.glob("embreex.libs/libembree4*"), *package.glob(".dylibs/libembree4*")])
    return found[0] if found else None


class Library:
    """The C functions the build needs, with their argument types (rtcore_*.h)."""

    def __init__(self, path: Path):
        lib = ctypes.CDLL(str(path))
        p, u, z = ctypes.c_void_p, ctypes.c_uint, ctypes.c_size_t
        signatures = {
            "rtcNewDevice": (p, [ctypes.c_char_p]), "rtcReleaseDevice": (None, [p]),
            "rtcGetDeviceError": (ctypes.c_int, [p]),
            "rtcNewScene": (p, [p]), "rtcReleaseScene": (None, [p]), "rtcSetSceneFlags": (None, [p, ctypes.c_int]),
            "rtcCommitScene": (None, [p]), "rtcAttachGeometry": (u, [p, p]),
            "rtcNewGeometry": (p, [p, ctypes.c_int]), "rtcReleaseGeometry": (None, [p]),
            "rtcCommitGeometry": (None, [p]),
            "rtcSetSharedGeometryBuffer": (None, [p, ctypes.c_int, u, ctypes.c_int, p, z, z, z]),
            "rtcIntersect16": (None, [p, p, p, p]), "rtcOccluded16": (None, [p, p, p, p]),
        }
        for name, (result, arguments) in signatures.items():
            function = getattr(lib, name)  # AttributeError: a symbol is missing
            function.restype, function.argtypes = result, arguments
            setattr(self, name, function)
        self.path = path
        self.query_addresses = {INTERSECT16: ctypes.cast(lib.rtcIntersect16, p).value,
                                OCCLUDED16: ctypes.cast(lib.rtcOccluded16, p).value}
        self._lib = lib  # keep the library loaded while its functions are in use


@lru_cache(maxsize=1)
def library() -> Library:
    """The loaded library with the kernels' symbols bound; EmbreeError if it cannot be loaded."""
    path = library_path()
    try:
        if path is None:
            raise OSError("embreex carries no libembree4")
        loaded = Library(path)
    except (OSError, AttributeError) as error:
        raise EmbreeError(f"Embree's C library could not be loaded from {path or 'embreex'} ({error}); "
                          "reinstall embreex") from None
    for name, address in loaded.query_addresses.items():
        binding.add_symbol(name, address)
    return loaded


def device_error(lib: Library, device: int | None, doing: str) -> None:
    """Raise EmbreeError if Embree recorded an error on `device` (rtcGetDeviceError also clears it)."""
    code = lib.rtcGetDeviceError(device)
    if code != 0:
        raise EmbreeError(f"Embree failed while {doing}: {ERRORS.get(code, f'error {code}')} (library {lib.path})")


class EmbreeScene:
    """A committed robust Embree scene of one triangle mesh on shared buffers; released with the object.

    vertices (V, 3) in the unit frame are rounded once into the float32 buffer Embree shares (padded by one
    float so that its 16-byte loads of the last vertex stay inside it); faces (F, 3) int32 are shared as
    they are. The object keeps both buffers alive as long as the scene.
    """

    def __init__(self, lib: Library, vertices: np.ndarray, faces: np.ndarray):
        self._lib = lib
        self.device = self.scene = None
        padded = np.empty(3 * len(vertices) + 1, np.float32)  # +1 float: rtcSetSharedGeometryBuffer's padding
        padded[:-1].reshape(-1, 3)[...] = vertices  # rounds float64 to float32 as astype would, without a copy
        padded[-1] = 0
        self._vertices, self._faces = padded, np.ascontiguousarray(faces, np.int32)
        self.device = lib.rtcNewDevice(None)
        if not self.device:
            device_error(lib, None, "creating a device")  # without a device, the error is the thread's
            raise EmbreeError(f"Embree could not create a device (library {lib.path})")
        self.scene = lib.rtcNewScene(self.device)
        lib.rtcSetSceneFlags(self.scene, RTC_SCENE_FLAG_ROBUST)
        if len(self._faces):
            geometry = lib.rtcNewGeometry(self.device, RTC_GEOMETRY_TYPE_TRIANGLE)
            lib.rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                           padded.ctypes.data, 0, 12, len(vertices))
            lib.rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                           self._faces.ctypes.data, 0, 12, len(self._faces))
            lib.rtcCommitGeometry(geometry)
            lib.rtcAttachGeometry(self.scene, geometry)
            lib.rtcReleaseGeometry(geometry)  # the scene holds it now
        device_error(lib, self.device, "preparing the triangle mesh")
        lib.rtcCommitScene(self.scene)
        device_error(lib, self.device, "building the BVH")

    def __del__(self):
        if self.scene:
            self._lib.rtcReleaseScene(self.scene)
        if self.device:
            self._lib.rtcReleaseDevice(self.device)
        self.scene = self.device = None


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
    return words, words.view(np.int32), valid, arguments


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
                words[TNEAR + lane] = 0
                words[TIME + lane] = 0
                words[TFAR + lane] = NO_LIMIT
                ints[MASK + lane] = -1
                ints[FLAGS + lane] = 0
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
def occluded_rays(scene, origins, directions, t_max, blocked):
    """blocked[k] = something lies on ray k within [0, t_max[k]], in packets of 16 consecutive rays."""
    words, ints, valid, arguments = _packet()
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
            words[TNEAR + lane] = 0
            words[TIME + lane] = 0
            ints[MASK + lane] = -1
            ints[FLAGS + lane] = 0
        rtc_occluded16(valid.ctypes.data, scene, words.ctypes.data, arguments.ctypes.data)
        # An occluded ray's tfar becomes −inf (rtcOccluded16's documented answer).
        for lane in range(lanes):
            blocked[first + lane] = words[TFAR + lane] < 0
