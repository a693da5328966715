"""Embree 4's C library, from the one embreex installs: loaded through ctypes, the kernels' query names
bound to its addresses, and scenes built on buffers shared with it (kernels/ray_queries.py queries them).

This is the renderer's one engine: embreex's wheels link their own modules against the libembree4 they
carry, so wherever embreex imports, this library loads. If it cannot (a missing file or symbol), `library()`
raises one EmbreeError saying so; LIBRARY_VARIABLE naming a file that is not the library (or a FIFO, never
opened) is the user's input: one OptionError naming the variable, exit 2.
Layouts and constants follow include/embree4/rtcore_scene.h, rtcore_geometry.h and rtcore_device.h.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
import stat
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import EmbreeError, OptionError

LIBRARY_VARIABLE = "RAYCAST_PHONG_EMBREE_LIBRARY"  # a path to use instead of embreex's own libembree4

# rtcore_common.h / rtcore_geometry.h / rtcore_buffer.h / rtcore_scene.h / rtcore_device.h constants.
RTC_GEOMETRY_TYPE_TRIANGLE = 0
RTC_BUFFER_TYPE_INDEX, RTC_BUFFER_TYPE_VERTEX = 0, 1
RTC_FORMAT_UINT3, RTC_FORMAT_FLOAT3 = 0x5003, 0x9003
RTC_SCENE_FLAG_COMPACT = 1 << 1         # a BVH of about 40 B a triangle instead of 95 (rtcore_scene.h)
RTC_SCENE_FLAG_ROBUST = 1 << 2          # watertight edges, no cracks between faces (as embreex's robust=True)
# From this many triangles the BVH is built compact: measured on 10⁶ boxes (12M triangles), 462 MB and 3.8 s of
# CPU to build against 1125 MB and 5.9–8.8 s, the same hits (tests/renderer/kernels/test_embree.py); below it the
# default layout's faster traversal is worth its memory (docs/performance.md, "Many objects").
COMPACT_FACES = 1 << 22
# From this many triangles the BVH is built by Embree's Morton-code builder (device config "tri_builder=morton", on
# the compact layout, the one whose Morton builder every CPU target has) instead of its binned SAH: measured on
# bunny-1m (1,111,216 triangles), 0.10-0.13 s of CPU to build against 0.37-0.46 s, while its 640 × 480 primary
# rays took 0.033 s of CPU against 0.025 (1920 × 1080: 0.097 against 0.080), the same image: a frame of a large
# mesh is mostly its build. Below it the SAH tree's faster traversal and the default layout are kept (every scene
# file's triangles, bit for bit). Should a library refuse the config, the SAH build is made instead.
MORTON_FACES = 1 << 18
MORTON_CONFIG = b"tri_builder=morton"
ERRORS = {1: "unknown error", 2: "invalid argument", 3: "invalid operation", 4: "out of memory",
          5: "unsupported CPU", 6: "cancelled"}


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
        from .kernels.ray_queries import INTERSECT16, OCCLUDED16  # the kernels' (numba): only once the library loads
        self.query_addresses = {INTERSECT16: ctypes.cast(lib.rtcIntersect16, p).value,
                                OCCLUDED16: ctypes.cast(lib.rtcOccluded16, p).value}
        self._lib = lib  # keep the library loaded while its functions are in use


@lru_cache(maxsize=1)
def library() -> Library:
    """The loaded library with the kernels' symbols bound; EmbreeError if it cannot be loaded."""
    path = library_path()
    chosen = os.environ.get(LIBRARY_VARIABLE)  # the user's choice: what is wrong with it is their input's fault
    if chosen:
        try:  # a FIFO would block dlopen for ever
            problem = None if stat.S_ISREG(os.stat(path).st_mode) else "not a regular file"
        except OSError as error:
            problem = f"{error.strerror}"
        if problem:
            raise OptionError(f"{LIBRARY_VARIABLE}={chosen[:200]}: {problem}; name Embree 4's library "
                              "(libembree4.so.4), or unset it to use embreex's")
    try:
        if path is None:
            raise OSError("embreex carries no libembree4")
        loaded = Library(path)
    except (OSError, AttributeError) as error:
        if chosen:
            raise OptionError(f"{LIBRARY_VARIABLE}={chosen[:200]}: not Embree 4's library ({str(error)[:200]}); "
                              "name libembree4.so.4, or unset it to use embreex's") from None
        raise EmbreeError(f"Embree's C library could not be loaded from {path or 'embreex'} ({error}); "
                          "reinstall embreex") from None
    from llvmlite import binding  # numba's LLVM: only once the library loads, not for the constants here
    for name, address in loaded.query_addresses.items():
        binding.add_symbol(name, address)
    return loaded


# Embree 4's CPU targets, best first, as its verbose device report names them (rtcNewDevice("verbose=1")).
TARGETS = ("AVX512", "AVX2", "AVXI", "AVX", "SSE4.2", "SSE2")


def picked_target(report: str) -> str | None:
    """The ISA Embree runs its kernels in: the best target that is both "(supported)" by the CPU and
    "(compile time enabled)" in the library, read from a verbose device report; None if it names none."""
    sets = {kind: set(line.rsplit("(", 1)[0].replace("Targets", " ").replace(":", " ").split())
            for line in report.splitlines() for kind in ("supported", "compile time enabled")
            if line.rstrip().endswith(f"({kind})")}
    both = sets.get("supported", set()) & sets.get("compile time enabled", set())
    return next((target for target in TARGETS if target in both), None)


def device_report(lib: Library) -> str:
    """What Embree prints about itself and this CPU when a device is made with "verbose=1" (its version,
    the CPU's ISA, its targets): captured from file descriptor 1, where the C library prints it."""
    import sys
    import tempfile
    libc = ctypes.CDLL(None)
    sys.stdout.flush()
    saved = os.dup(1)
    with tempfile.TemporaryFile() as capture:
        try:
            os.dup2(capture.fileno(), 1)
            device = lib.rtcNewDevice(b"verbose=1")
            if device:
                lib.rtcReleaseDevice(device)
            libc.fflush(None)
        finally:
            os.dup2(saved, 1)
            os.close(saved)
        capture.seek(0)
        return capture.read().decode(errors="replace")


def device_error(lib: Library, device: int | None, doing: str) -> None:
    """Raise EmbreeError if Embree recorded an error on `device` (rtcGetDeviceError also clears it)."""
    code = lib.rtcGetDeviceError(device)
    if code != 0:
        raise EmbreeError(f"Embree failed while {doing}: {ERRORS.get(code, f'error {code}')} (library {lib.path})")


class EmbreeScene:
    """A committed robust Embree scene of one triangle mesh on shared buffers; released with the object.
    A mesh of MORTON_FACES triangles or more is built by Embree's Morton builder on the compact layout, and one
    of COMPACT_FACES or more gets the compact layout (less than half the memory) in any case.

    vertices (V, 3) in the unit frame are rounded once into the float32 buffer Embree shares (padded by one
    float so that its 16-byte loads of the last vertex stay inside it); faces (F, 3) int32 are shared as
    they are. The object keeps both buffers alive as long as the scene. `builder` names the build used:
    "morton" or "sah".
    """

    def __init__(self, lib: Library, vertices: np.ndarray, faces: np.ndarray):
        self._lib = lib
        self.device = self.scene = None
        padded = np.empty(3 * len(vertices) + 1, np.float32)  # +1 float: rtcSetSharedGeometryBuffer's padding
        padded[:-1].reshape(-1, 3)[...] = vertices  # rounds float64 to float32 as astype would, without a copy
        padded[-1] = 0
        self._vertices, self._faces = padded, np.ascontiguousarray(faces, np.int32)
        self.builder = "morton" if len(self._faces) >= MORTON_FACES else "sah"
        if self.builder == "morton" and not self._build(MORTON_CONFIG, RTC_SCENE_FLAG_COMPACT, check=False):
            self._release()
            self.builder = "sah"
        if self.builder == "sah":
            self._build(None, RTC_SCENE_FLAG_COMPACT if len(self._faces) >= COMPACT_FACES else 0)

    def _build(self, config: bytes | None, flags: int, check: bool = True) -> bool:
        """Make the device and the scene with `config` and `flags` (besides ROBUST) and commit it; whether
        Embree reported no error (with `check`, an error raises EmbreeError instead)."""
        lib, count = self._lib, len(self._faces)
        self.device = lib.rtcNewDevice(config)
        if not self.device:
            if not check:
                return False
            device_error(lib, None, "creating a device")  # without a device, the error is the thread's
            raise EmbreeError(f"Embree could not create a device (library {lib.path})")
        self.scene = lib.rtcNewScene(self.device)
        lib.rtcSetSceneFlags(self.scene, RTC_SCENE_FLAG_ROBUST | flags)
        if count:
            geometry = lib.rtcNewGeometry(self.device, RTC_GEOMETRY_TYPE_TRIANGLE)
            lib.rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                           self._vertices.ctypes.data, 0, 12, len(self._vertices) // 3)
            lib.rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                           self._faces.ctypes.data, 0, 12, count)
            lib.rtcCommitGeometry(geometry)
            lib.rtcAttachGeometry(self.scene, geometry)
            lib.rtcReleaseGeometry(geometry)  # the scene holds it now
        if check:
            device_error(lib, self.device, "preparing the triangle mesh")
        elif lib.rtcGetDeviceError(self.device):
            return False
        lib.rtcCommitScene(self.scene)
        if check:
            device_error(lib, self.device, "building the BVH")
        return lib.rtcGetDeviceError(self.device) == 0

    def _release(self) -> None:
        if self.scene:
            self._lib.rtcReleaseScene(self.scene)
        if self.device:
            self._lib.rtcReleaseDevice(self.device)
        self.scene = self.device = None

    def __del__(self):
        self._release()


