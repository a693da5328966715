"""No stale kernels: an edit to any module a cached kernel compiles in reaches the next render.

numba's own cache checks only the file a kernel is defined in; shading's `_shade_rays` inlines
illumination's `illuminate`. These tests work on a copy of the package (its own __pycache__), import it
in fresh interpreters, and edit it between runs, as a developer would.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import raycast_phong

PACKAGE = Path(raycast_phong.__file__).resolve().parent

# Render a small Phong sphere with the diffuse layer; report the kernel's cache statistics.
RENDER = """
import json, sys
import numpy as np
import raycast_phong as rp
from raycast_phong.renderer.kernels import shading
scene = rp.validate_scene({
    "render": {"width": 24, "height": 24, "shading": "phong"},
    "camera": {"position": [0, 0, 4], "fov": 40},
    "lights": [{"type": "point", "position": [2, 2, 3]}],
    "objects": [{"shape": "icosphere", "subdivisions": 2}],
    "output": {"aovs": ["diffuse"]},
})
result = rp.render(scene, threads=1)
np.save(sys.argv[1], np.stack([result.image, result.aovs["diffuse"]]))
# The shading kernel, which compiles illumination's helpers into itself, and the tile kernel, which calls it by
# address (its module reads no illumination.py).
from raycast_phong.renderer.kernels import tile
counts = {}
for name, dispatcher in (("shade", shading._shade_rays), ("tile", tile.render_band)):
    stats = dispatcher.stats
    counts[name] = {"hits": sum(stats.cache_hits.values()), "misses": sum(stats.cache_misses.values())}
print(json.dumps(counts))
"""

KEYS = "import json; from raycast_phong import jit; print(json.dumps(jit.kernel_keys()))"
# How many signatures of each named kernel (module.function) the kernel cache holds.
CACHED = ("import json, sys; from raycast_phong import jit; print(json.dumps({name: "
          "len(list(jit.cache_folder().rglob(name + '-*.nbc'))) for name in sys.argv[1:]}))")


@pytest.fixture
def package_copy(tmp_path):
    """A copy of the installed package's sources under tmp_path/src, and a runner importing it."""
    shutil.copytree(PACKAGE, tmp_path / "src" / "raycast_phong", ignore=shutil.ignore_patterns("__pycache__"))
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env["PYTHONPATH"] = str(tmp_path / "src")

    def run(code: str, *args: str) -> str:
        done = subprocess.run([sys.executable, "-c", code, *args], env=env, cwd=tmp_path, capture_output=True,
                              text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        return done.stdout.strip().splitlines()[-1]

    return tmp_path / "src" / "raycast_phong", run


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert text.count(old) == 1, f"{path.name} no longer has {old!r}: update this test"
    path.write_text(text.replace(old, new))


def test_each_kernel_module_s_key_covers_every_module_it_reads_and_only_those(package_copy):
    copy, run = package_copy
    keys = json.loads(run(KEYS))
    assert {"renderer.kernels.shading", "renderer.kernels.tile", "renderer.kernels.camera", "geometry.kernels",
            "io.meshes.obj_plain"} <= keys.keys(), keys

    def changed() -> set[str]:
        nonlocal keys
        before, keys = keys, json.loads(run(KEYS))
        assert keys.keys() == before.keys()
        return {name for name in keys if keys[name] != before[name]}

    # tolerances.py holds constants the kernels freeze in; no kernel is defined there. shading.py and shadows.py
    # read it; the camera, the tile and the mesh preparation do not.
    edit(copy / "tolerances.py", "NO_DIRECTION = 1e-6", "NO_DIRECTION = 2e-6")
    assert changed() == {"renderer.kernels.shading", "renderer.kernels.shadows"}
    # batch/ is a tool on top of the pipeline: editing it must not throw away compiled kernels.
    tool = copy / "tools" / "batch" / "run.py"
    tool.write_text(tool.read_text() + "\n# an edit\n")
    assert changed() == set()
    # The scene schema is no kernel code (kernels read renderer/kernels/layout.py's tables): a new message
    # there recompiles nothing, nor does a kind's key. So is the packing of a Scene into those tables
    # (renderer/pack.py).
    edit(copy / "values" / "fields.py", 'return check_number(value, what="a whole number")',
         'return check_number(value, what="an integer")')
    edit(copy / "shapes" / "box.py", '    """A box centred on the origin, its sides along the axes."""',
         '    """A box centred on the origin, its sides along the axes."""\n    bevel: float = 0.0')
    (copy / "renderer" / "pack.py").write_text((copy / "renderer" / "pack.py").read_text() + "\n# an edit\n")
    assert changed() == set()
    # ... while the layout the kernels read is, for the modules that read it (through illumination.py too).
    edit(copy / "renderer" / "kernels" / "layout.py", "MAX_LIGHTS = 63", "MAX_LIGHTS = 62")
    reading_layout = {f"renderer.kernels.{name}"
                      for name in ("illumination", "ray_queries", "shading", "shadows", "texture", "tile")}
    assert changed() == reading_layout
    # ... and what the layout itself imports (codes.py's material columns), transitively.
    (copy / "codes.py").write_text((copy / "codes.py").read_text() + "\n# an edit\n")
    assert changed() == reading_layout
    # A helper inlined into shading's kernel: shading.py's key, not the tile's that calls it by address.
    edit(copy / "renderer" / "kernels" / "illumination.py", "lit = weight * n_dot_l\n", "lit = weight * n_dot_l \n")
    assert changed() == {"renderer.kernels.illumination", "renderer.kernels.shading"}
    # In the package's own __pycache__ the cache keeps a folder per module and key: the folders of keys the tree
    # no longer has are removed (and the older layout's, one folder for all), a kernel's from outside the
    # package is kept.
    cache = copy / "__pycache__" / "raycast-phong-kernels"
    current = cache / f"renderer.kernels.tile-{keys['renderer.kernels.tile']}"
    older = copy / "__pycache__" / "raycast-phong-kernels-0123456789abcdef"
    for folder in (cache / "renderer.kernels.tile-0123456789abcdef", older, cache / "outside.mine-0123456789abcdef",
                   current):
        folder.mkdir(parents=True)
    assert run("from raycast_phong import jit; print(jit.cache_folder())") == str(cache)
    assert sorted(cache.parent.glob("raycast-phong-kernels*")) == [cache]
    assert sorted(path.name for path in cache.iterdir()) == ["outside.mine-0123456789abcdef", current.name]


def test_every_kernel_module_s_key_changes_with_numba_s_version(monkeypatch):
    """A cached kernel is machine code numba made: another numba must not load it (its runtime, its calling
    conventions), so numba's version is in every key. Catches the key made of the sources alone."""
    import numba

    from raycast_phong import jit
    before = jit.kernel_keys.__wrapped__()
    monkeypatch.setattr(numba, "__version__", numba.__version__ + "+another")
    after = jit.kernel_keys.__wrapped__()
    assert after.keys() == before.keys() and all(after[name] != before[name] for name in before), (before, after)


@pytest.mark.slow
def test_the_first_render_says_it_compiles_and_keeps_compilation_out_of_the_frame(cold_package):
    """After an install (an empty cache) `render` says it is compiling before it does, and reports those
    seconds apart: the frame, and the Mrays/s printed from it, hold none of them. The next run says nothing."""
    out, err = cold_package.cold["stdout"], cold_package.cold["stderr"]
    # said once, naming the shading kernels (a global scene: after its shadow rays', which compile first)
    assert "shading kernels" in err and "13-18 s of CPU" in err and err.count("compiling") == 1, err
    compile_s = float(out.split("compile ")[1].split("s")[0])
    frame_s = float(out.split("frame ")[1].split("s")[0])
    assert compile_s > frame_s, out  # seconds of compilation against milliseconds of a 32×12 frame
    out, err = cold_package.warm["stdout"], cold_package.warm["stderr"]
    assert "compiling" not in err and "compile " not in out, (out, err)
    # Loading the cached kernels (numba's set-up in a new process, ~0.25 s) is reported apart too: the frame
    # of 384 rays holds none of it.
    kernels_s = float(out.split("kernels ")[1].split("s")[0])
    frame_s = float(out.split("frame ")[1].split("s")[0])
    assert kernels_s > frame_s, out
    # float64 after float32: the same kernels in another signature are a compile too, said as one. numba says
    # which kernels this process saves to its cache and which it loads (NUMBA_DEBUG_CACHE, on stdout).
    wide = cold_package.python(cold_package.cli, "--set", "render.precision=float64",
                               env={"NUMBA_DEBUG_CACHE": "1", "RAYCAST_PHONG_COMPILE_PROCESSES": "2"})
    assert "compiling the float64 shading kernels" in wide.stderr and wide.stderr.count("compiling") == 1, wide.stderr
    assert "the first time a scene needs float64" in wide.stderr, wide.stderr  # why now: the precision, not an install
    assert "compile " in wide.stdout and "kernels " not in wide.stdout, wide.stdout
    # With its helper (split_compile.py; asked for, whatever the machine's load) the shading kernel compiles in
    # the helper: this process loads it, and compiles the callee the helper loads (the textured material, with the
    # texture sampler it calls, and the screen-space weights). Each kernel is compiled once, in one signature per
    # precision. The tile kernel calls the shading kernel by its address: it compiles here without it.
    saved = [line for line in wide.stdout.splitlines() if "data saved" in line]
    loaded = [line for line in wide.stdout.splitlines() if "data loaded" in line]
    assert not any("shading._shade_rays" in line for line in saved), wide.stdout
    assert any("shading._shade_rays" in line for line in loaded), wide.stdout
    assert all(any(name in line for line in saved) for name in (
        "texture.sample", "shading._textured_material", "shading._screen_weights", "tile.render_band"))
    # (Counted by the copy itself, under the shared lock: the edit test's run removes shading's folder.)
    counts = json.loads(cold_package.python(CACHED, "shading._shade_rays", "texture.sample", "shading._screen_weights",
                                            "shading._textured_material", "tile.render_band",
                                            "shadows.cast_shadows").stdout)
    # The default scene is in local mode: global mode's shadow rays (called by address) never compiled.
    assert counts == {**dict.fromkeys(counts, 2), "shadows.cast_shadows": 0}, counts


@pytest.mark.slow
def test_an_edit_to_an_inlined_helper_reaches_the_cached_kernel(cold_package, tmp_path):
    """On the shared copy, alone with it while it is edited (ColdPackage.editing puts it back as it was)."""
    copy = cold_package.source

    def run(*args: str, alone: bool = False) -> dict:
        done = (cold_package.run if alone else cold_package.python)(RENDER, *args)
        return json.loads(done.stdout.strip().splitlines()[-1])

    first = run(str(tmp_path / "first.npy"))
    again = run(str(tmp_path / "again.npy"))
    for kernel in ("shade", "tile"):
        assert again[kernel]["misses"] == 0 and again[kernel]["hits"] > 0, (first, again)
    # Double the diffuse term in illumination.py only: shading.py, where the cached kernel lives, is untouched.
    illumination = copy / "renderer" / "kernels" / "illumination.py"
    with cold_package.editing(illumination):
        edit(illumination, "lit = weight * n_dot_l\n", "lit = (weight + weight) * n_dot_l\n")  # 2w, exactly
        edited = run(str(tmp_path / "edited.npy"), alone=True)
    assert edited["shade"]["misses"] > 0, "the cached _shade_rays was loaded although diffuse_terms changed"
    # ... and only the kernels that read illumination.py compile again: the tile kernel is loaded as it was.
    assert edited["tile"] == again["tile"], edited
    (before, diffuse), (after, _) = np.load(tmp_path / "first.npy"), np.load(tmp_path / "edited.npy")
    np.testing.assert_array_equal(np.load(tmp_path / "again.npy")[0], before)
    # image' = image + diffuse exactly, up to float32 rounding of the sum (a few ulps of the pixel).
    assert diffuse.max() > 0.3
    np.testing.assert_allclose(after, before + diffuse, rtol=1e-6, atol=1e-7)
