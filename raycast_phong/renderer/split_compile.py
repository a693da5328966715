"""A first compile of the frame kernels on two cores at once.

numba compiles one kernel at a time in a process: a fresh cache compiles the default scene's kernels in about 13 s
of one core's CPU, 5-6 of them the shading kernel (shading._shade_rays). tile.render_band calls it by address
(by_address.py), so render_band compiles without it. Here a helper process compiles _shade_rays into the same
kernel cache while this process compiles two of its callees (which the helper then loads), the warm-up scene's
geometry kernels and render_band; when render_band is first called it asks for the shading kernel's address, and
this process waits for the helper and loads its result (jit.compiled_elsewhere).
The kernels and the cache files are numba's own either way: a helper that fails, or a signature that differs, only
means this process compiles that kernel itself, as it would alone.

The helper is given the arguments render_band passes _shade_rays, for a band of no rays (by_address.shading_arguments),
and shading inputs packed from a geometry of no faces (unprepared_shading), so it starts compiling as soon as it has
imported numba, without waiting for this process's geometry kernels.
"""

from __future__ import annotations

import os
import queue
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

import numpy as np

from .. import jit
from ..geometry.mesh_repair import WINDING_KERNELS
from ..io.system import available_memory, usable_cores
from .by_address import shading_arguments
from .kernels import shading
from .kernels.layout import Material

SHADE = jit.kernel_name(shading._shade_rays)
PROCESSES = "RAYCAST_PHONG_COMPILE_PROCESSES"  # 1: compile in this process alone; 2: always with the helper
HELPER = "import sys; from raycast_phong.renderer.split_compile import helper; helper(*sys.argv[1:])"
# Run before HELPER, first thing: on Linux the kernel kills the helper when the thread that started it ends
# (PR_SET_PDEATHSIG = 1, SIGKILL), and it ends at once if that parent is already gone. helper()'s own watch starts
# only after its imports (about a second): a command killed meanwhile would leave the helper running that long.
ORPHAN_GUARD = ("import sys, os\n"
                "if sys.platform.startswith('linux'):\n"
                "    import ctypes\n"
                "    ctypes.CDLL(None).prctl(1, 9)\n"
                "if os.getppid() != int(sys.argv[2]):\n"
                "    os._exit(3)\n")
# The helper's own memory: its peak resident size compiling the default scene's shading kernel was 258 MB (the
# command's own, 253 MB); on a machine with less available it is not started (the command compiles alone).
HELPER_BYTES = 400 << 20
# A helper whose CPU time stands still this long while it is waited for is stopped (SIGSTOP) or stuck: it is
# ended and the kernel compiles here. A compiling helper spends CPU every tick, even on a machine at load 16;
# where its CPU time cannot be read, ten times as long without a word from it.
STALL_SECONDS = 10.0
POLL_SECONDS = 0.5


cores = usable_cores  # the cores this process may run on (tests set it)


def two_processes() -> bool:
    """Whether a first compile may start its helper: RAYCAST_PHONG_COMPILE_PROCESSES=1 never, =2 whenever there is
    a kernel cache; otherwise when this process may run on two cores or more and one of them is free now (idle_cores:
    the machine's idle time over a tenth of a second, not the load average, which still counts a job that ended
    a minute ago, such as the pip install before a first render), with HELPER_BYTES of memory available for the
    helper. The two processes spend about 15 % more CPU than one (each compiles numba's own helpers, and the
    helper starts Python): on a busy machine that only makes the compile longer."""
    if not (jit.LIGHT_LOAD and jit.BY_ADDRESS):  # the helper's result is waited for and loaded through both
        return False
    setting = os.environ.get(PROCESSES, "").strip()
    if setting in ("1", "2"):
        return setting == "2"
    room = available_memory()
    return cores() >= 2 and (room is None or room >= HELPER_BYTES) and idle_cores() >= 0.75


def idle_cores(seconds: float = 0.1) -> float:
    """How many of the machine's cores were idle over the last `seconds` (Linux's /proc/stat); elsewhere the cores
    less the load average over the last minute."""
    def idle_and_total() -> tuple[int, int]:
        with open("/proc/stat") as stat:
            fields = [int(value) for value in stat.readline().split()[1:]]
        return fields[3] + (fields[4] if len(fields) > 4 else 0), sum(fields)  # idle + iowait, all

    try:
        idle, total = idle_and_total()
        time.sleep(seconds)
        idle_after, total_after = idle_and_total()
        return (idle_after - idle) / max(total_after - total, 1) * (os.cpu_count() or 1)
    except (OSError, ValueError, IndexError):
        try:
            return max(0.0, (os.cpu_count() or 1) - os.getloadavg()[0])
        except (AttributeError, OSError):  # no load average (Windows)
            return float(cores())


def warm_scene(precision: str):
    """The 2×2 scene the kernels are typed with: global mode, one point light, an icosahedron."""
    from ..scene.schema import validate_scene
    return validate_scene({"render": {"width": 2, "height": 2, "mode": "global", "precision": precision},
                           "lights": [{"type": "point", "position": [2, 2, 3]}],
                           "objects": [{"shape": "icosphere", "subdivisions": 0}]}, source="warm-up")


def unprepared_shading(precision: str):
    """The warm-up scene's ShadingInputs packed from a geometry of no faces: pack.prepare_shading gives every array
    its dtype and rank whatever it holds, so these type as prepare()'s, and neither process waits for the geometry
    kernels (the icosahedron's normals) before the shading kernel's compile can start."""
    from ..records import Frame, Geometry
    from .pack import camera_rig, prepare_shading
    from .plan import build_plan
    scene = warm_scene(precision)
    plan = build_plan(scene)
    none = Geometry(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), np.int32), face_normals=np.zeros((0, 3)),
                    corner_normals=np.zeros((0, 3, 3)), face_material=np.zeros(0, np.int32),
                    face_model=np.zeros(0, np.int8), face_object=np.zeros(0, np.int32))
    no_flags = (0, 0)  # the flags are values, not types (prepare_shading packs empty maps alike)
    return prepare_shading(scene, none, camera_rig(scene), Frame(np.zeros(3), 1.0), no_flags, plan.real)


def callee_signatures(inputs) -> dict:
    """The kernels _shade_rays calls that this process compiles first, each with its argument types as _shade_rays
    calls it: _textured_material (the material table, the texels, their table, the corner UVs and densities, a
    Material, its row and the face (int32), three weights, the footprint in float64, 1, the (3,) cast), which
    compiles texture.sample, and _screen_weights (three weights, the vertices, a face's three corners (int32), the
    eye (a slice of the view row), the camera, 1). The helper waits to hear each is cached (Aside.tell) instead of
    compiling it. These are ~1.6 s of CPU: this process then compiles the warm-up scene's geometry kernels and
    render_band, ~4.5 s more, which with them is about what the helper spends on the rest of _shade_rays.
    Written down, not derived (numba types a call only while compiling its caller): a test compiles _shade_rays
    cold and holds these to the types numba gave its calls."""
    from numba import typeof, types
    real = typeof(inputs.one)
    material = typeof(Material(*[inputs.one] * len(Material._fields)))
    return {shading._textured_material: (typeof(inputs.materials), typeof(inputs.texels),
                                         typeof(inputs.texture_table), typeof(inputs.corner_uv),
                                         typeof(inputs.uv_density), material, types.int32, types.int32, real, real,
                                         real, types.float64, real, typeof(np.zeros(3, inputs.materials.dtype))),
            shading._screen_weights: (real, real, real, typeof(inputs.vertices), types.int32, types.int32,
                                      types.int32, typeof(inputs.viewing[0:3]), typeof(inputs.camera), real)}


class Aside:
    """The helper of one precision's compile (shading_compiled_aside), if one runs. It hears on its standard input
    the name of each kernel this process has put in the cache for it, and says on its standard output each task it
    has finished ("shade", "winding"): pipes, nothing to remove afterwards."""

    def __init__(self, precision: str, winding: bool = False):
        self.precision = precision
        self.process: subprocess.Popen | None = None
        self.finished: set[str] = set()
        self.waits: list[str] = []
        if jit.cache_folder() is None:
            return
        inputs = unprepared_shading(precision)
        # The cache's index first: two_processes() watches the machine for a tenth of a second, and a warm start
        # (the kernels cached) must not pay for it.
        tasks = [task for task, needed in (
            ("shade", not jit.cached(shading._shade_rays, shading_arguments(inputs))),
            ("winding", winding and not all(jit.cached(kernel) for kernel in WINDING_KERNELS))) if needed]
        if not tasks or not two_processes():
            return
        self.start(tasks)
        if self.process is not None and "shade" in tasks:  # meanwhile its callees here, first: the helper loads them
            for kernel, signature in callee_signatures(inputs).items():
                kernel.compile(signature)
                self.tell(jit.kernel_name(kernel))

    def start(self, tasks: list[str]) -> None:
        package_parent = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ,
                   PYTHONPATH=os.pathsep.join(filter(None, [package_parent, os.environ.get("PYTHONPATH")])))
        try:
            self.process = subprocess.Popen([sys.executable, "-c", ORPHAN_GUARD + HELPER, self.precision,
                                             str(os.getpid()), ",".join(tasks)],
                                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                            stderr=subprocess.DEVNULL, env=env, text=True)
        except OSError:  # no interpreter to start (an embedded Python): everything compiles here, as alone
            return
        self.lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=_read_lines, args=(self.process.stdout, self.lines), daemon=True).start()
        kernels = {"shade": [SHADE], "winding": [jit.kernel_name(kernel) for kernel in WINDING_KERNELS]}
        for task in tasks:
            for name in kernels[task]:
                jit.compiled_elsewhere[name] = lambda task=task: self.wait_for(task)
                self.waits.append(name)

    def wait_for(self, task: str) -> None:
        """Return once the helper says it has finished `task`, has ended, or has stalled (stopped by SIGSTOP, or
        stuck: its CPU time still for STALL_SECONDS): a stalled helper is ended, and what it did not cache compiles
        here, as alone."""
        moved, cpu = time.monotonic(), _cpu_seconds(self.process.pid)
        while task not in self.finished:
            try:
                line = self.lines.get(timeout=POLL_SECONDS)
            except queue.Empty:
                now, spent = time.monotonic(), _cpu_seconds(self.process.pid)
                if spent is not None and spent != cpu:
                    moved, cpu = now, spent
                if now - moved >= (STALL_SECONDS if spent is not None else 10 * STALL_SECONDS):
                    self.process.kill()
                    return
                continue
            if not line:  # the helper has ended (or failed): what it did not cache compiles here
                return
            moved = time.monotonic()
            self.finished.add(line.strip())

    def tell(self, name: str) -> None:
        """Tell the helper that `name` is in the cache (a helper that has ended hears nothing)."""
        with suppress(OSError):
            self.process.stdin.write(name + "\n")
            self.process.stdin.flush()

    def close(self) -> None:
        for name in self.waits:
            jit.compiled_elsewhere.pop(name, None)
        if self.process is not None:
            if self.process.poll() is None:
                self.process.kill()
            self.process.wait()
            for stream in (self.process.stdin, self.process.stdout):
                with suppress(OSError):
                    stream.close()


def _read_lines(stream, lines: queue.Queue) -> None:
    """Each line the helper says, then "" when it has ended: wait_for waits on the queue with a timeout, which a
    pipe's readline has not."""
    with suppress(OSError, ValueError):  # closed under the thread by Aside.close
        for line in stream:
            lines.put(line)
    lines.put("")


def _cpu_seconds(pid: int) -> float | None:
    """The process's CPU time so far (Linux's /proc/PID/stat, in clock ticks), or None where it cannot be read."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            fields = stat.read().rsplit(b")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


@contextmanager
def shading_compiled_aside(precision: str, winding: bool = False) -> Iterator[Aside]:
    """Within the block, a compile of _shade_rays in `precision` (a cache miss) waits for a helper process that
    compiles it, while this process compiles two of its callees and goes on with the rest; with `winding` (a scene
    with a mesh file), the helper then compiles the winding's kernels (mesh_repair.WINDING_KERNELS), which a miss
    here waits for too. The helper starts at once when one of them is missing (for _shade_rays: for the types
    prepare() gives it, unprepared_shading); none without a kernel cache, nor when two_processes() says no (one
    core, a busy machine, RAYCAST_PHONG_COMPILE_PROCESSES=1).
    The helper is stopped when the block ends, however it ends, and ends itself if this process goes away."""
    aside = Aside(precision, winding)
    try:
        yield aside
    finally:
        aside.close()


def helper(precision: str, parent: str, tasks: str = "shade") -> None:
    """The helper's work, its `tasks` in turn (comma-separated), each said on standard output when done: "shade",
    _shade_rays for `precision` into the kernel cache, the callees the parent compiles (callee_signatures) loaded
    from it once the parent says they are there; "winding", mesh_repair.WINDING_KERNELS. Ends at once if the
    parent goes away (its pipe closes, or the process is gone)."""
    parent_id = int(parent)

    def watch() -> None:
        while os.getppid() == parent_id:
            time.sleep(0.2)
        os._exit(3)

    threading.Thread(target=watch, daemon=True).start()
    heard: set[str] = set()

    def told(name: str) -> Callable[[], None]:
        def wait() -> None:
            while name not in heard:
                line = sys.stdin.readline()
                if not line:  # the parent is gone
                    os._exit(3)
                heard.add(line.strip())
        return wait

    for task in tasks.split(","):
        if task == "shade":
            inputs = unprepared_shading(precision)
            for name in map(jit.kernel_name, callee_signatures(inputs)):
                jit.compiled_elsewhere[name] = told(name)
            shading._shade_rays(*shading_arguments(inputs))
        elif task == "winding":
            from ..geometry.mesh_repair import winding_signatures
            for kernel, signature in winding_signatures().items():
                if kernel in WINDING_KERNELS:
                    kernel.compile(signature)
        print(task, flush=True)
