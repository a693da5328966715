"""Options and fixtures shared by the whole test suite.

    pytest --update-references    rewrite the reference images instead of comparing against them

The option and the `assert_image_matches` / `image_references` fixtures come from raycast-phong's own pytest
plugin (raycast_phong/pytest_plugin.py, registered by the installed package's pytest11 entry point).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest

pytest_plugins = ["pytester"]  # the plugin's own tests (tests/project/test_pytest_plugin.py) run pytest inside pytest


# One low-poly red sphere in the middle, lit from the upper right: flat, Gouraud and Phong differ on it,
# the corners are background. Tests format in the size (and an [output] table if they need one).
TINY_SCENE = """\
ambient = [0.1, 0.1, 0.1]

[render]
width = {width}
height = {height}

[camera]
position = [0, 0, 4]
look_at = [0, 0, 0]
fov = 40

[[lights]]
position = [2, 2, 3]

[materials.red]
ka = [1.0, 0.3, 0.3]
kd = [0.9, 0.2, 0.2]
ks = [0.6, 0.6, 0.6]

[[objects]]
shape = "icosphere"
subdivisions = 1
material = "red"
"""


def write_tiny_scene(folder: Path, width: int, height: int, extra: str = "") -> Path:
    """TINY_SCENE at width × height, with `extra` TOML appended, as folder/tiny.toml."""
    path = folder / "tiny.toml"
    path.write_text(TINY_SCENE.format(width=width, height=height) + extra, encoding="utf-8")
    return path


@pytest.fixture
def in_tmp_path(tmp_path, monkeypatch):
    """Run in tmp_path, so a default-named output can never land in the repository; no debug tracebacks."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("RAYCAST_PHONG_DEBUG", raising=False)


def pixel_centre_rays(rig, width: int, height: int):
    """The eye and the unit direction (H, W, 3) through every pixel centre of a perspective camera_rig,
    written from the scene format (x right, y up, row 0 at the top), independent of camera.py."""
    import numpy as np
    x = (np.arange(width) + 0.5) / width * 2 - 1
    y = 1 - (np.arange(height) + 0.5) / height * 2
    sx, sy = np.meshgrid(x * rig.half_width, y * rig.half_height)
    d = rig.forward + sx[..., None] * rig.right + sy[..., None] * rig.up
    return rig.eye, d / np.linalg.norm(d, axis=-1, keepdims=True)


@pytest.fixture(autouse=True, scope="session")
def error_logs_in_the_session_folder(tmp_path_factory):
    """Internal-error tracebacks (cli.common._traceback_log) of this run, and of the commands it starts, go to
    a folder of the session's own instead of piling up as raycast-phong-error-*.log in /tmp."""
    import os
    folder = tmp_path_factory.mktemp("error-logs")
    before = os.environ.get("RAYCAST_PHONG_ERROR_LOGS")
    os.environ["RAYCAST_PHONG_ERROR_LOGS"] = str(folder)
    yield folder
    if before is None:
        os.environ.pop("RAYCAST_PHONG_ERROR_LOGS", None)
    else:
        os.environ["RAYCAST_PHONG_ERROR_LOGS"] = before


# The session's scenes: float32 and float64 with a mesh file that has no normals (the crease split's kernels
# too), and the text readers' scans (OBJ, PLY, STL). Made ready in a fresh process each, as a user's first render
# would.
WARM_UP = """
import sys
import trimesh
from pathlib import Path
from raycast_phong.renderer.warmup import ready_kernels
from raycast_phong.scene.schema import validate_scene
folder, precision, mode, mesh = Path(sys.argv[1]), *sys.argv[2:5]
objects = [{"shape": "icosphere", "crease_angle": 30}]  # creased: the crease split in this precision
if mesh != "-":
    trimesh.creation.icosphere(1).export(folder / mesh)
    objects.append({"shape": "mesh", "path": str(folder / mesh)})  # a mesh file's merge and winding
ready_kernels(validate_scene({"render": {"precision": precision, "mode": mode},
                              "lights": [{"type": "point", "position": [2, 2, 3]}], "objects": objects}, source="t"))
if "obj" in sys.argv[5:]:  # the text readers' kernels (OBJ, PLY, STL), not the mesh preparation the other compiles
    from raycast_phong.io.meshes import obj_plain, obj_polygons, ply_lists, stl_ascii
    obj_plain.warm_up()
    obj_polygons.warm_up()
    ply_lists.warm_up()
    stl_ascii.warm_up()
"""
# (precision, mode, mesh file or "-", [obj]): between them every kernel a test may call, each compiled by one of the
# two: float32 with global mode's shadow rays (called by address: only a scene in global mode brings them) and the
# text readers; float64 with a mesh file's preparation (merge, winding; the same kernels in either precision).
WARM_UPS = (("float32", "global", "-", "obj"), ("float64", "local", "ball.stl"))


def pytest_configure(config):
    """Every kernel compiled (or loaded from the cache) before the first test, as after an install's first render.

    A render on an empty cache says "compiling ..." first (renderer/warmup.py); tests that run the CLI check its
    exact output, so which of them came first on a fresh clone must not decide what they see. The tests of the
    notice itself stand in for a cache miss (compiles.compiling, as numba's cache reports one).
    The two precisions compile at once, in two processes (a compile is one core's work; numba writes each
    kernel's cache atomically), once for the whole run, started here, in the process that starts xdist's workers:
    the workers collect the tests meanwhile (about 11 s of CPU each, most of it pytest rewriting asserts; no test
    module calls a kernel when it is imported), and no test starts before both are done (pytest_runtestloop)."""
    if hasattr(config, "workerinput") or config.option.collectonly or config.option.help:
        return  # an xdist worker: the cache is ready
    import tempfile
    folder = tempfile.TemporaryDirectory()
    runs = []
    for n, specification in enumerate(WARM_UPS):
        Path(folder.name, str(n)).mkdir()
        # Already one process a core: no compile helpers besides (renderer/split_compile.py).
        runs.append(subprocess.Popen([sys.executable, "-c", WARM_UP, str(Path(folder.name, str(n))), *specification],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     env={**os.environ, "RAYCAST_PHONG_COMPILE_PROCESSES": "1"},
                                     preexec_fn=_killed_with_parent()))
    config.stash[WARMING] = (folder, runs)


def _killed_with_parent():
    """Linux: a function for Popen's preexec_fn that has the child killed when pytest ends, however it ends (a
    SIGTERM leaves pytest no clean-up); None elsewhere (^C still stops it: pytest_runtestloop, pytest_unconfigure).
    libc is looked up here, in the parent: the child only calls prctl."""
    import ctypes
    import signal
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    return lambda: prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG


WARMING = pytest.StashKey[tuple]()


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtestloop(session):
    """Wait for the warm-up (pytest_configure) before the first test: here, xdist's workers have collected or are
    collecting (under -n 0, this process has)."""
    runs = session.config.stash.get(WARMING, (None, []))[1]
    if session.testsfailed and not session.config.option.continue_on_collection_errors:
        runs = []  # pytest is about to stop on its collection errors (-n 0): nothing to wait for
    try:
        for run in runs:
            output, _ = run.communicate()
            if run.returncode:
                raise pytest.UsageError(f"the kernels' warm-up failed:\n{output}")
    finally:
        _stop_warm_up(session.config)  # on an error (or ^C) the other one is not left compiling
    return (yield)


def pytest_unconfigure(config):
    """A run that ends before its test loop (a collection error, ^C) leaves no warm-up behind."""
    _stop_warm_up(config)


def _stop_warm_up(config) -> None:
    folder, runs = config.stash.get(WARMING, (None, []))
    for run in runs:
        if run.poll() is None:
            run.kill()
            run.wait()
    if folder is not None:
        folder.cleanup()


# The package as a fresh install meets it: a copy of its sources with an empty kernel cache, compiled once.
# Three tests need kernels compiled in a fresh process (the first render's notice, a cached kernel that calls
# Embree loading in another process, an edit reaching a cached kernel). Each compile of the renderer costs about
# 25 s of CPU, so they share one copy, made once per run under a lock (under xdist, every worker finds the one
# the first made): `render` runs into its empty cache once, and again; the tests read those two runs and go on
# from the warm cache, under a shared lock; the edit takes it alone and leaves the copy as it found it.

@dataclass(frozen=True)
class ColdPackage:
    """The copy (`source`, imported through `env`'s PYTHONPATH in `folder`) and its two `render` runs' output."""
    folder: Path
    source: Path
    env: dict[str, str]
    cold: dict[str, str]  # stdout, stderr of `render` into the empty cache: it compiles, and says so
    warm: dict[str, str]  # the same command again: it loads what the first one cached
    cli: str              # that command (`render` of the default scene, 32×12), as `python -c` code

    def run(self, code: str, *args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
        """`python -c code args` importing the copy (with `env` added to its environment), with no lock; asserts
        it exits 0."""
        done = subprocess.run([sys.executable, "-c", code, *args], env={**self.env, **(env or {})},
                              cwd=self.folder, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, done.stderr
        return done

    def python(self, code: str, *args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
        """`run`, while no edit is under way."""
        with _locked(self.folder / "lock", shared=True):
            return self.run(code, *args, env=env)

    @contextmanager
    def editing(self, *paths: Path):
        """Alone with the copy while `paths` are edited; then their text and times, and the kernel cache as it
        was, are put back (cache_folder removes the folders of other keys from the package's own __pycache__:
        the edited run would remove those of the modules it reads edited)."""
        with _locked(self.folder / "lock", shared=False):
            kept = {path: (path.read_bytes(), path.stat()) for path in paths}
            cache, aside = self.source / "__pycache__" / "raycast-phong-kernels", self.folder / "aside"
            shutil.copytree(cache, aside)
            try:
                yield
            finally:
                for path, (text, info) in kept.items():
                    path.write_bytes(text)
                    os.utime(path, ns=(info.st_atime_ns, info.st_mtime_ns))
                shutil.rmtree(cache)
                aside.rename(cache)


@contextmanager
def _locked(path: Path, shared: bool):
    import fcntl
    with open(path, "a+b") as handle:
        fcntl.flock(handle, fcntl.LOCK_SH if shared else fcntl.LOCK_EX)
        yield


@pytest.fixture(scope="session")
def cold_package(tmp_path_factory) -> ColdPackage:
    import json

    import raycast_phong
    base = tmp_path_factory.getbasetemp()
    folder = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "cold-package"
    folder.mkdir(exist_ok=True)
    source = folder / "src" / "raycast_phong"
    # The copy's own __pycache__ holds its kernels: no NUMBA_CACHE_DIR. cwd is the folder, so that `-c` code
    # imports the copy (the working folder comes first on sys.path).
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env["PYTHONPATH"] = str(folder / "src")
    cli = ("import sys; sys.argv = ['raycast-phong', 'render', '--width', '32', '--height', '12', '-o', "
           f"{str(folder / 'x.png')!r}, *sys.argv[1:]]; from raycast_phong.cli import app; app()")
    made = folder / "runs.json"
    with _locked(folder / "lock", shared=False):
        if not made.exists():
            shutil.copytree(Path(raycast_phong.__file__).resolve().parent, source,
                            ignore=shutil.ignore_patterns("__pycache__"))
            # The example scenes where a wheel has them (setup.py's build step): the default scene is one.
            shutil.copytree(Path(raycast_phong.__file__).resolve().parents[1] / "scenes", source / "data" / "scenes",
                            ignore=shutil.ignore_patterns("__pycache__", "*.py"))
            package = ColdPackage(folder, source, env, {}, {}, cli)
            runs = [package.run(cli) for _ in range(2)]
            made.write_text(json.dumps([{"stdout": r.stdout, "stderr": r.stderr} for r in runs]))
    cold, warm = json.loads(made.read_text())
    return ColdPackage(folder, source, env, cold, warm, cli)
