"""What a warm start of the program does not pay for (issue 22, benchmarks/bench_cli.py): numba's typing and
lowering registries when every kernel comes from the cache (jit._CacheLoadedAsIs), and the interpreter's teardown
after the command (cli.main). Each is checked in a fresh process, where it happens."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# Modules numba imports only to set up its typing and lowering registries (CPUContext.load_additional_registries).
REGISTRY_MODULES = ("numba.typed.typeddict", "numba.np.arraymath", "numba.np.npyimpl", "numba.cpython.listobj")

FACE_NORMAL = ("import sys, numpy as np\nfrom raycast_phong.geometry.kernels import face_normals_into\n"
               "unit, area = np.zeros((1, 3)), np.zeros(1)\n"
               "face_normals_into(np.array([[0.0, 0, 0], [2, 0, 0], [0, 2, 0]]), np.array([[0, 1, 2]]), unit, area)\n"
               "assert area[0] == 4.0 and unit[0].tolist() == [0, 0, 1], (area, unit)\n")


def python(code: str, *arguments: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *arguments], capture_output=True, text=True, cwd=ROOT,
                          env=env, timeout=600)


def test_a_cached_kernel_loads_without_numba_s_registries_and_a_compile_still_loads_them(tmp_path):
    """Into an empty cache (NUMBA_CACHE_DIR) the kernel compiles: numba's registries load, without the BLAS probe
    (no scipy.linalg). From the cache, in the next process, it runs with none of them loaded; a kernel compiled
    after that in the same process (numpy functions: their registries) still compiles and gives numpy's values."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    loaded = f"print([name for name in {REGISTRY_MODULES!r} if name in sys.modules], 'scipy.linalg' in sys.modules)\n"
    compiled = python(FACE_NORMAL + loaded, env=env)
    assert compiled.returncode == 0, compiled.stderr
    assert compiled.stdout.strip() == f"{list(REGISTRY_MODULES)} False"  # the control: a compile loads them all
    assert list(tmp_path.rglob("*.face_normals_into-*.nbi")), "the kernel was not cached"
    cached = python(FACE_NORMAL + loaded + "from numba import njit\nx = np.linspace(0, 1, 5)\n"
                    "print(njit(lambda x: np.sin(x).sum())(x) == np.sin(x).sum(), 'numba.np.arraymath' in sys.modules)",
                    env=env)
    assert cached.returncode == 0, cached.stderr
    assert cached.stdout.split("\n")[:2] == ["[] False", "True True"], cached.stdout


ALLOCATING = ("import numpy as np\nfrom raycast_phong.jit import kernel\n\n\n@kernel()\ndef allocate(n):\n"
              "    a = np.empty(n)  # np.empty's implementation: an environment of numba.np.arrayobj\n"
              "    a[:] = 2.0\n    return a.sum() + min(n, 3)  # min's: one of numba.cpython.builtins\n")
CALL = ("import sys\nsys.path.insert(0, sys.argv[1])\nfrom allocating import allocate\n"
        "print(allocate(4), 'numba.np.arrayobj' in sys.modules)\n"
        "try:\n    allocate(-1)\nexcept ValueError as error:\n    print(error)\n")


def test_a_cached_kernel_loads_without_importing_the_modules_of_numba_s_implementations_it_holds(tmp_path):
    """A kernel calling np.empty holds numba's implementation of it, whose environment numba rebuilds at a load by
    importing numba.np.arrayobj (26–38 ms): loaded from the cache (jit._environment_as_is) it runs, and raises
    np.empty's own error, without that import; compiled (the control, the first process) it imports it."""
    (tmp_path / "allocating.py").write_text(ALLOCATING, encoding="utf-8")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    runs = [python(CALL, str(tmp_path), env=env) for _ in range(2)]
    assert all(run.returncode == 0 for run in runs), runs[-1].stderr
    assert runs[0].stdout.splitlines() == ["11.0 True", "negative dimensions not allowed"], runs[0].stdout
    assert runs[1].stdout.splitlines() == ["11.0 False", "negative dimensions not allowed"], runs[1].stdout


PROBE = ("import atexit, sys, threading\n"
         "class Teardown:\n    def __del__(self):\n        print('torn down', flush=True)\n"
         "kept = Teardown()  # its __del__ runs when the interpreter is torn down\n"
         "def told():  # whether pydantic scanned the installed packages for its plugins\n"
         "    loader = sys.modules.get('pydantic.plugin._loader')\n"
         "    import gc\n"
         "    print('atexit ran', 'plugins', loader is not None and loader._plugins is not None, gc.get_threshold()[0],"
         " flush=True)\n"
         "atexit.register(told)\n"
         "if sys.argv.pop(1) == 'thread':\n"
         "    first = threading.main_thread()  # the thread ends once Python's exit has begun\n"
         "    threading.Thread(target=lambda: (first.join(), print('thread done', flush=True))).start()\n"
         "from raycast_phong.cli import ENTRY\nENTRY()\n")


def test_the_program_ends_without_the_interpreter_s_teardown_after_its_exit_handlers(tmp_path):
    """cli.main (the console script) runs the atexit handlers, keeps the command's status and its output, and ends
    the process without tearing the interpreter down (0.2–0.3 s of a warm render); app() still exits as Python
    does (the control: the probe sees the teardown), and so does main while another thread of the program runs.
    main leaves pydantic's plugins off (no scan of the installed packages for them; app() scans: the control) and
    the cyclic collector's young pass at 10,000 allocations (app(): Python's 700)."""
    scene = tmp_path / "tiny.toml"
    scene.write_text('[render]\nwidth = 8\nheight = 6\n[[objects]]\nshape = "icosphere"\nsubdivisions = 1\n',
                     encoding="utf-8")
    render = ["render", str(scene), "-q", "-o", str(tmp_path / "out.png")]
    done = python(PROBE.replace("ENTRY", "main"), "plain", *render)
    assert (done.returncode, done.stdout.split()) == (0, ["atexit", "ran", "plugins", "False", "10000"]), \
        done.stdout + done.stderr
    assert (tmp_path / "out.png").stat().st_size > 0 and done.stderr == ""
    control = python(PROBE.replace("ENTRY", "app"), "plain", *render)
    python_s = ["atexit", "ran", "plugins", "True", "700", "torn", "down"]  # Python's exit, the scan, its collector
    assert (control.returncode, control.stdout.split()) == (0, python_s), control.stderr
    refused = python(PROBE.replace("ENTRY", "main"), "plain", "render", "--width", "0", str(scene))
    assert refused.returncode == 2 and refused.stdout.split()[:2] == ["atexit", "ran"], refused.stdout + refused.stderr
    assert len(refused.stderr.splitlines()) == 1 and refused.stderr.startswith("error: "), refused.stderr
    waited = python(PROBE.replace("ENTRY", "main"), "thread", "--help")
    assert waited.returncode == 0, waited.stderr
    words = waited.stdout.split()
    assert words[-9:] == ["thread", "done", "atexit", "ran", "plugins", "False", "10000", "torn", "down"], words


# Modules a warm render of the default scene never needs (issue 46): each was, or could be, imported on its way.
NOT_ON_THE_DEFAULT_PATH = (
    "raycast_phong.io.meshes",  # the mesh formats' registry: a .toml scene is no mesh file, nor is "warm-up"
    "raycast_phong.io.meshes.source",
    "raycast_phong.io.textures",
    "trimesh", "PIL", "scipy.linalg", "matplotlib",
    "yaml",  # numba's config reads a .numba_config.yaml with it: there is none in the working folder
)
LOADED = ("import atexit, json, sys\n"
          "atexit.register(lambda: print(json.dumps(sorted(sys.modules))))\n"
          "from raycast_phong.cli import main\nsys.argv[0] = 'raycast-phong'\nmain()\n")


def test_a_render_of_the_default_scene_imports_none_of_what_it_does_not_use(tmp_path):
    """The modules a default render had no use for stay out of the process (each costs start-up): a fresh process
    renders the default scene (warm, after a first render: the path a user waits for) and none of
    NOT_ON_THE_DEFAULT_PATH is in sys.modules at its exit; the control is that the render happened."""
    output = tmp_path / "d.png"
    command = ["render", "scenes/default.toml", "-q", "-o", str(output)]
    for _ in range(2):  # the first may compile (a fresh cache): the second is the warm start
        run = python(LOADED, *command)
        assert run.returncode == 0, run.stderr
    loaded = json.loads(run.stdout.splitlines()[-1])
    assert output.stat().st_size > 0 and "raycast_phong.renderer.kernels.tile" in loaded
    assert [name for name in NOT_ON_THE_DEFAULT_PATH if name in loaded] == []


CONFIG_READ = "import sys, raycast_phong.jit, numba\nprint('yaml' in sys.modules, numba.config.CACHE_DIR)\n"


def test_numba_s_config_file_is_read_where_there_is_one_and_pyyaml_not_imported_where_there_is_none(tmp_path):
    """numba's import reads a .numba_config.yaml in the working folder with PyYAML, which it imports either way
    (9 ms of a start-up): jit imports numba without it where there is no such file, and with it, the file's
    settings taken as numba takes them, where there is one. Afterwards `import yaml` works as ever."""
    folder = tmp_path / "with-config"
    folder.mkdir()
    (folder / ".numba_config.yaml").write_text(f"cache_dir: {tmp_path / 'from-yaml'}\n", encoding="utf-8")
    env = {key: value for key, value in os.environ.items() if key != "NUMBA_CACHE_DIR"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    read = subprocess.run([sys.executable, "-c", CONFIG_READ], capture_output=True, text=True, cwd=folder, env=env,
                          timeout=600)
    assert read.returncode == 0 and read.stdout.split() == ["True", str(tmp_path / "from-yaml")], read.stderr
    none = subprocess.run([sys.executable, "-c", CONFIG_READ + "import yaml\nprint(yaml.safe_load('a: 1'))\n"],
                          capture_output=True, text=True, cwd=tmp_path, env=env, timeout=600)
    assert none.returncode == 0, none.stderr
    assert [line.strip() for line in none.stdout.splitlines()] == ["False", "{'a': 1}"], none.stdout


NRT_COUNTED = ("import numba.core.runtime.nrtdynmod as nrt\ncompiled = []\nmake = nrt.create_nrt_module\n"
               "nrt.create_nrt_module = lambda context: (compiled.append(1), make(context))[1]\n")


def test_numba_s_runtime_functions_come_from_the_kernel_cache_after_the_first_process(tmp_path):
    """numba compiles its NRT's functions (a small LLVM module) at each process's first kernel call, 15-18 ms of a
    start-up: jit.initialise_nrt keeps them in the kernel cache as object code. The first process compiles them
    (the control), the next loads them and its cached kernel runs, and np.empty (the NRT allocates) still works
    and raises its own error; a cache file that is cut short, altered or not the NRT's is compiled over, once."""
    (tmp_path / "allocating.py").write_text(ALLOCATING, encoding="utf-8")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    code = NRT_COUNTED + CALL + "print('compiled', len(compiled))\n"

    def run() -> list[str]:
        done = python(code, str(tmp_path), env=env)
        assert done.returncode == 0, done.stderr
        return done.stdout.splitlines()

    assert run()[-1] == "compiled 1"
    saved = list((tmp_path / "cache").rglob("nrt-*.nbc"))
    assert len(saved) == 1, saved
    assert run() == ["11.0 False", "negative dimensions not allowed", "compiled 0"]
    whole = saved[0].read_bytes()
    for damaged in (whole[:len(whole) // 2], whole[:-1] + bytes([whole[-1] ^ 1]), b"not a cache file",
                    bytes(32) + whole[32:]):  # the file: the payload's sha256 (32 bytes), then the payload
        saved[0].write_bytes(damaged)
        assert run() == ["11.0 False", "negative dimensions not allowed", "compiled 1"]
        assert run()[-1] == "compiled 0"  # written whole again by the compile


NOT_FOR_A_REFUSAL = ("numba", "llvmlite", "OpenImageIO", "raycast_phong.renderer.prepare", "raycast_phong.jit")


@pytest.mark.parametrize("case", ["over the budget", "a map of zeros named .png", "too many lights"])
def test_a_scene_refused_before_rendering_loads_neither_numba_nor_the_renderer(tmp_path, case):
    """A scene `render` refuses from its plan and memory check (renderer/fit.py) exits 2 with its one line having
    imported neither numba (0.15 s), LLVM, OpenImageIO nor the renderer's stages: a refused input costs its
    validation alone (issue 46). The control: the same scene's render, unrefused, imports them."""
    scene = tmp_path / "s.toml"
    body = '[render]\nwidth = 8\nheight = 6\n[[objects]]\nshape = "icosphere"\nsubdivisions = 1\n'
    options, expected = [], "error: "
    if case == "over the budget":
        options, expected = ["--width", "4000", "--height", "3000", "--max-memory", "10M"], "above the 10 MB budget"
    elif case == "a map of zeros named .png":
        (tmp_path / "zeros.png").write_bytes(bytes(64))
        body += 'material = "m"\n[materials.m]\nkd_map = "zeros.png"\n'
        expected = "is not a PNG file"
    else:
        body = body.replace("[render]\n", '[render]\nmode = "global"\n') + '[[lights]]\nposition = [1, 2, 3]\n' * 64
        expected = "global mode handles at most 63 lights"
    scene.write_text(body, encoding="utf-8")
    run = python(LOADED, "render", str(scene), "-q", "-o", str(tmp_path / "out.png"), *options)
    assert run.returncode == 2 and expected in run.stderr and len(run.stderr.splitlines()) == 1, run.stderr
    loaded = json.loads(run.stdout.splitlines()[-1])
    assert [name for name in NOT_FOR_A_REFUSAL if name in loaded] == []
    if case == "over the budget":  # the control
        done = python(LOADED, "render", str(scene), "-q", "-o", str(tmp_path / "out.png"))
        assert done.returncode == 0, done.stderr
        assert set(NOT_FOR_A_REFUSAL) <= set(json.loads(done.stdout.splitlines()[-1]))


LINKED = ("import numpy as np\nfrom raycast_phong.jit import kernel\n\n\n@kernel()\ndef callee(x):\n"
          "    return x * 2.0 + 1.0\n")
LINKING = ("from linked import callee\nfrom raycast_phong.jit import kernel\n\n\n@kernel()\ndef caller(x):\n"
           "    return callee(x) - 1.0  # numba links callee's code library into caller's\n")
PARSES = ("import sys\nsys.path.insert(0, sys.argv[1])\nimport llvmlite.binding as llvm\n"
          "from numba.core.registry import cpu_target\nfrom raycast_phong import jit\n"
          "jit.initialise_nrt(cpu_target.target_context)  # its own library first: not counted\n"
          "parsed = []\nparse = llvm.parse_bitcode\n"
          "llvm.parse_bitcode = lambda data: (parsed.append(1), parse(data))[1]\n"
          "from linked import callee\nprint(callee(3.0), len(parsed), jit.LINK_LAZILY)\n"
          "if sys.argv[2] == 'link':\n    from linking import caller\n    print(caller(3.0), len(parsed))\n")


def test_a_cached_kernel_s_bitcode_is_parsed_only_when_a_compile_links_it(tmp_path):
    """numba parses a cached kernel's bitcode at each load to learn the names it defines (40 % of loading the
    kernels); jit._LinkedWhenAsked reads them from a file the first load writes, and parses the bitcode only when
    a kernel compiled later links the loaded one. Compiled (the first process), loaded by numba's parse (the
    second, the control: 1 parse), loaded unparsed (the third: 0), then a caller compiled in that process links
    it (parsed then) and gets callee's value; a symbols file that is altered or cut short is parsed over once."""
    (tmp_path / "linked.py").write_text(LINKED, encoding="utf-8")
    (tmp_path / "linking.py").write_text(LINKING, encoding="utf-8")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}

    def run(then: str = "") -> list[list[str]]:
        done = python(PARSES, str(tmp_path), then, env=env)
        assert done.returncode == 0 and not done.stderr, done.stderr
        return [line.split() for line in done.stdout.splitlines()]

    assert run()[0][0] == "7.0"  # compiled into the cache
    assert run() == [["7.0", "1", "True"]]  # numba's parse, its names kept
    symbols = list((tmp_path / "cache").rglob("symbols-*"))
    assert len(symbols) == 1, symbols
    loaded, linked = run("link")
    assert loaded == ["7.0", "0", "True"] and linked[0] == "6.0" and int(linked[1]) >= 1
    whole = symbols[0].read_bytes()
    for damaged in (whole[:-1] + bytes([whole[-1] ^ 1]), whole[:len(whole) // 2], b""):
        symbols[0].write_bytes(damaged)
        assert run() == [["7.0", "1", "True"]]
        assert run() == [["7.0", "0", "True"]]  # written whole again


@pytest.mark.parametrize(("model", "needs_pil"), [("scenes/meshes/still_life.glb", False),
                                                  ("tests/data/models/BoxTextured.glb", True)])
def test_a_glb_without_maps_renders_without_pil_or_trimesh(tmp_path, model, needs_pil):
    """A GLB is read by the package's own glTF reader: one without maps imports neither trimesh nor PIL (9 ms);
    the control, a textured one, imports PIL to weigh and decode its image."""
    run = python(LOADED, "render", model, "-q", "-o", str(tmp_path / "out.png"), "--width", "32", "--height", "24")
    assert run.returncode == 0, run.stderr
    loaded = set(json.loads(run.stdout.splitlines()[-1]))
    assert ("PIL" in loaded, "trimesh" in loaded) == (needs_pil, False)
