"""A first compile split over two processes (renderer/split_compile.py, jit.compiled_elsewhere): a kernel another
process compiles into the cache is waited for and loaded, never compiled twice; the helper never outlives its block.
(The split of a real cold compile is checked on the cold package's float64 run: test_kernel_cache.py.)"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from raycast_phong import jit
from raycast_phong.renderer import split_compile

ROOT = Path(__file__).resolve().parents[3]

KERNELS = textwrap.dedent("""
    from raycast_phong.jit import kernel

    @kernel()
    def plus_one(x):
        return x + 1
""")

# The main process: plus_one is "compiled elsewhere" by a second interpreter; the first call waits for it, loads
# its code and compiles nothing (compiles.told hears every kernel numba is about to compile here).
MAIN = textwrap.dedent("""
    import subprocess, sys
    import tiny
    from raycast_phong import jit
    from raycast_phong.compiles import told
    other = "import tiny; tiny.plus_one(1)" if sys.argv[1] == "compiles" else "pass"
    jit.compiled_elsewhere[jit.kernel_name(tiny.plus_one)] = (
        lambda: subprocess.run([sys.executable, "-c", other], check=True))
    with told(lambda name, signature: None) as heard:
        answer = tiny.plus_one(41)
    print(answer, heard, jit.compiled_elsewhere)
""")


@pytest.mark.slow
@pytest.mark.parametrize("elsewhere", ["compiles", "fails"])
def test_a_kernel_compiled_elsewhere_is_waited_for_and_loaded(tmp_path, elsewhere):
    (tmp_path / "tiny.py").write_text(KERNELS)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONPATH=os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-c", MAIN, elsewhere], env=env, cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    # The other process compiled it: loaded here, nothing compiled. It did not: compiled here, as alone.
    heard = "[]" if elsewhere == "compiles" else "['tiny.plus_one']"
    assert done.stdout.split() == ["42", heard, "{}"], done.stdout


@pytest.fixture
def helper_sleeps(monkeypatch):
    """A helper that only sleeps, on a cache said to hold no shading kernel, on two cores."""
    monkeypatch.setattr(split_compile, "HELPER", "import time; time.sleep(60)")
    monkeypatch.setattr(split_compile, "two_processes", lambda: True)
    monkeypatch.setattr(jit, "cached", lambda dispatcher, arguments=None: False)


def test_the_helper_is_stopped_however_the_block_ends(helper_sleeps):
    with pytest.raises(KeyboardInterrupt):
        with split_compile.shading_compiled_aside("float32") as aside:
            assert aside.process is not None and aside.process.poll() is None  # started at once: no cache
            assert list(jit.compiled_elsewhere) == [split_compile.SHADE]
            raise KeyboardInterrupt  # Ctrl-C during the compile
    assert aside.process.poll() is not None and jit.compiled_elsewhere == {}


BUSY = "import sys, time\nstart = time.monotonic()\nwhile time.monotonic() - start < {seconds}: pass\n" \
       "print('shade', flush=True)\ntime.sleep(60)"


@pytest.mark.parametrize("stopped", [False, True])
def test_a_stopped_helper_is_ended_and_a_busy_one_waited_for(helper_sleeps, monkeypatch, stopped):
    """A helper stopped by SIGSTOP never answers: the wait ends once its CPU time has stood still for
    STALL_SECONDS (the command then compiles the kernel itself). A helper that computes is waited for as long as
    it takes, though it says nothing meanwhile."""
    monkeypatch.setattr(split_compile, "STALL_SECONDS", 1.0)
    monkeypatch.setattr(split_compile, "POLL_SECONDS", 0.1)
    monkeypatch.setattr(split_compile, "HELPER", BUSY.format(seconds=600 if stopped else 3))
    with split_compile.shading_compiled_aside("float32") as aside:
        if stopped:
            time.sleep(0.5)  # started: its CPU time moves
            aside.process.send_signal(signal.SIGSTOP)
        start = time.monotonic()
        jit.compiled_elsewhere[split_compile.SHADE]()
        waited = time.monotonic() - start
        if stopped:
            # Ended one STALL_SECONDS after its CPU time stopped, plus polls; below the 10 × STALL_SECONDS it waits
            # only where the CPU time cannot be read (no /proc), with room for a slow machine.
            assert 1.0 <= waited < 6 and aside.process.wait(timeout=30) is not None, waited
        else:
            assert aside.finished == {"shade"} and aside.process.poll() is None, waited


def test_no_helper_when_two_processes_would_not_help(helper_sleeps, monkeypatch):
    monkeypatch.setattr(split_compile, "two_processes", lambda: False)
    with split_compile.shading_compiled_aside("float32") as aside:
        assert aside.process is None and jit.compiled_elsewhere == {}


@pytest.mark.parametrize(("setting", "cores", "idle", "room", "helper"), [
    ("", 2, 1.9, 8 << 30, True), ("", 2, 0.5, 8 << 30, False), ("", 1, 1.0, 8 << 30, False),
    ("", 8, 2.0, None, True), ("", 2, 1.9, 200 << 20, False),
    ("1", 8, 8.0, 8 << 30, False), ("2", 1, 0.0, 8 << 30, True), ("3", 2, 1.9, 8 << 30, True)])
def test_a_helper_when_a_core_and_its_memory_are_free_or_the_user_says(monkeypatch, setting, cores, idle, room,
                                                                         helper):
    """Two processes spend ~15 % more CPU than one: only worth it with a core free now, and the helper's memory
    (HELPER_BYTES) available (None: not known)."""
    monkeypatch.setenv(split_compile.PROCESSES, setting)
    monkeypatch.setattr(split_compile, "cores", lambda: cores)
    monkeypatch.setattr(split_compile, "idle_cores", lambda: idle)
    monkeypatch.setattr(split_compile, "available_memory", lambda: room)
    assert split_compile.two_processes() is helper


def test_idle_cores_are_the_idle_share_of_the_machine_now(monkeypatch):
    """From two readings of /proc/stat's first line: the idle and iowait ticks over all ticks, times the cores."""
    import io
    readings = iter(["cpu  100 0 100 200 0 0 0 0 0 0\n", "cpu  150 0 100 290 10 0 0 0 0 0\n"])
    monkeypatch.setattr(split_compile, "open", lambda path: io.StringIO(next(readings)), raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    # ticks 400 -> 550: 150, of which idle 90 and iowait 10: two thirds of the machine's two cores idle
    assert split_compile.idle_cores(0.0) == pytest.approx(2 * 100 / 150)


def test_idle_cores_fall_back_to_the_load_average(monkeypatch):
    def no_stat(path):
        raise FileNotFoundError(path)
    monkeypatch.setattr(split_compile, "open", no_stat, raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 4)
    monkeypatch.setattr(os, "getloadavg", lambda: (2.5, 1.0, 1.0))
    assert split_compile.idle_cores(0.0) == 1.5


def test_the_helper_is_given_the_types_render_band_gives_the_shading_kernel():
    """shading_arguments' whole empty arrays type as render_band's slices (C-contiguous along the first axis),
    so the helper's _shade_rays is the one render_band asks for."""
    import numpy as np
    from numba import njit, typeof

    @njit
    def slices(face, directions, rgb, n):
        return face[:n], directions[:n], rgb[0:n]

    whole = (np.empty(4, np.int32), np.empty((4, 3), np.float32), np.empty((4, 2, 3), np.float32))
    slices(*whole, 2)
    assert slices.nopython_signatures[0].return_type == typeof(whole)


def test_a_warm_start_does_not_stop_to_look_at_the_machine(monkeypatch):
    """With the shading kernel cached, no helper is considered: two_processes() (a tenth of a second watching the
    machine's idle time) is never asked, so a warm start does not pay for it."""
    looked = []
    monkeypatch.setattr(split_compile, "two_processes", lambda: looked.append(True) or True)
    monkeypatch.setattr(jit, "cached", lambda dispatcher, arguments=None: True)
    with split_compile.shading_compiled_aside("float32") as aside:
        pass
    assert looked == [] and aside.process is None


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_the_helper_types_the_shading_kernel_as_prepare_does(precision):
    """unprepared_shading packs the warm-up scene's inputs from a geometry of no faces, so that the helper need not
    wait for the geometry kernels: every field types as prepare()'s (a differing type would make the command
    compile _shade_rays itself, after waiting for the helper)."""
    from numba import typeof

    from raycast_phong.renderer.prepare import prepare
    ready = prepare(split_compile.warm_scene(precision))
    specimen = split_compile.unprepared_shading(precision)
    assert [typeof(value) for value in specimen] == [typeof(value) for value in ready.shading]
    assert typeof(split_compile.shading_arguments(specimen)) == typeof(
        split_compile.shading_arguments(ready.shading))


def test_a_kernel_called_by_address_must_return_what_its_caller_reads():
    """jit.ByAddress checks the callee's return type when its address is asked: a caller reading another type
    through the pointer would read garbage. The shadow rays' stand-in returns int64, as cast_shadows does."""
    from numba import types

    from raycast_phong.renderer import by_address
    from raycast_phong.renderer.kernels import shadows
    assert by_address.shadow_caster(False).ready() > 0
    wrong = jit.ByAddress(shadows.no_shadow_rays, by_address.shadow_arguments(), types.float64)
    with pytest.raises(TypeError, match="returns int64, not float64"):
        wrong.ready()


def test_the_winding_kernels_are_shared_out_with_the_types_a_mesh_file_gives_them():
    """mesh_repair.winding_signatures are the signatures repair_winding calls the kernels with (a merged mesh file's
    float64 vertices and int64 faces), so what the helper (WINDING_KERNELS) and the command compile by signature
    is what the render loads, and the helper's task leaves the others to the command."""
    import numpy as np

    from raycast_phong.geometry import mesh_repair
    vertices = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [2, 1, 3]])  # closed and consistent: the volume's sign
    mesh_repair.repair_winding(vertices, faces)
    faces[3] = faces[3, ::-1]  # one face turned: the orientation
    mesh_repair.repair_winding(vertices, faces)
    signatures = mesh_repair.winding_signatures()
    for kernel, signature in signatures.items():
        assert tuple(signature) in kernel.signatures, (kernel, kernel.signatures)
    assert set(mesh_repair.WINDING_KERNELS) < set(signatures)


PLAIN = textwrap.dedent("""
    import hashlib, sys
    import raycast_phong as rp
    from raycast_phong import jit
    from raycast_phong.renderer import by_address
    from raycast_phong.renderer.kernels import shading, shadows
    from raycast_phong.renderer.warmup import ready_kernels
    scene = rp.load_scene(sys.argv[1], ["render.width=40", "render.height=30"])
    print(jit.PLAIN, jit.LIGHT_LOAD, jit.BY_ADDRESS, jit.NRT_CACHED)
    print(ready_kernels(scene, lambda line: print("announced"))[0])
    print(by_address.shadow_caster(True) is shadows.cast_shadows)
    print(hashlib.sha256(rp.render(scene).image.tobytes()).hexdigest())
""")


@pytest.mark.slow
def test_with_the_fast_paths_off_the_callees_are_linked_and_the_image_is_the_same(tmp_path):
    """RAYCAST_PHONG_PLAIN_NUMBA=1 turns off every fast path on numba's internals (jit.PLAIN): numba's own cache
    load and its runtime functions compiled in each process, callees linked into render_band instead of handed by
    address, one compile process. A global-mode scene (both callees) then compiles with plain numba, announced, and
    gives the bits the fast paths give; the second process compiles render_band again (numba caches no kernel
    taking a dispatcher), announced too."""
    import hashlib

    import raycast_phong as rp
    scene = str(ROOT / "scenes" / "shadows.toml")
    env = {**os.environ, "RAYCAST_PHONG_PLAIN_NUMBA": "1", "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    runs = [subprocess.run([sys.executable, "-c", PLAIN, scene], capture_output=True, text=True, env=env,
                           timeout=600) for _ in range(2)]
    for run in runs:
        assert run.returncode == 0 and not run.stderr, run.stderr
    first, second = (run.stdout.split("\n") for run in runs)
    assert first[0] == "True False False False" and first[-3] == "True"  # the shadow rays' handle: the dispatcher
    assert not list((tmp_path / "cache").rglob("nrt-*")), "numba's runtime functions were cached"
    assert first[1:3] == second[1:3] == ["announced", "compile"]
    fast = rp.render(rp.load_scene(scene, ["render.width=40", "render.height=30"])).image
    assert first[-2] == second[-2] == hashlib.sha256(fast.tobytes()).hexdigest()


CALLEES = textwrap.dedent("""
    import sys
    from numba import typeof
    from raycast_phong.renderer import split_compile
    from raycast_phong.renderer.by_address import shading_arguments
    from raycast_phong.renderer.kernels import shading
    inputs = split_compile.unprepared_shading(sys.argv[1])
    shading._shade_rays.compile(tuple(typeof(argument) for argument in shading_arguments(inputs)))
    for kernel, signature in split_compile.callee_signatures(inputs).items():
        print(tuple(signature) in kernel.signatures, kernel.py_func.__name__, kernel.signatures)
""")


@pytest.mark.slow
def test_the_callees_compiled_first_are_typed_as_the_shading_kernel_calls_them(tmp_path):
    """split_compile.callee_signatures writes down the argument types _shade_rays calls _textured_material and
    _screen_weights with, so this process compiles them while the helper compiles the rest. If a call site's types
    drift from them, this process compiles a kernel nobody calls and the helper compiles the callee again (a
    silent second longer). Here numba types the calls itself: a cold compile of _shade_rays alone (an empty
    cache, no helper) compiles each callee for the types of its call, and those must be the written-down ones."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), split_compile.PROCESSES: "1"}
    done = subprocess.run([sys.executable, "-c", CALLEES, "float32"], capture_output=True, text=True, env=env,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.strip().splitlines()
    assert len(lines) == 2 and all(line.startswith("True ") for line in lines), done.stdout


# A command holding a helper that only sleeps: it prints the helper's process id, then waits to be killed.
KILLED_PARENT = textwrap.dedent("""
    import time
    from raycast_phong import jit
    from raycast_phong.renderer import split_compile
    split_compile.HELPER = "import time; time.sleep(60)"
    split_compile.two_processes = lambda: True
    jit.cached = lambda dispatcher, arguments=None: False
    with split_compile.shading_compiled_aside("float32") as aside:
        print(aside.process.pid, flush=True)
        time.sleep(60)
""")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the parent-death signal is Linux's")
def test_a_helper_dies_with_a_command_killed_before_any_cleanup(tmp_path):
    """SIGKILL leaves the command no handler and no `finally`: the helper must not outlive it (it lived on for
    1.1-1.8 s after a SIGTERM, in its imports, before its own watch started; this sleeping one for a minute)."""
    parent = subprocess.Popen([sys.executable, "-c", KILLED_PARENT], stdout=subprocess.PIPE, text=True, cwd=tmp_path,
                              env=dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache")))
    helper = int(parent.stdout.readline())
    time.sleep(0.3)  # past its guard: a helper started and sleeping
    assert Path(f"/proc/{helper}").exists()
    parent.kill()
    parent.wait(timeout=30)
    deadline = time.monotonic() + 5
    while Path(f"/proc/{helper}").exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    gone = not Path(f"/proc/{helper}").exists()
    if not gone:
        os.kill(helper, signal.SIGKILL)
    assert gone
