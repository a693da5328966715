"""The project's own promises: README commands, CI script, published schema, packaged default scene."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import raycast_phong as rp
from raycast_phong.scene.schema import scene_json_schema

ROOT = Path(__file__).resolve().parents[2]


def readme_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    return re.findall(r"```sh\n(python3 -m venv[^\n]*)\n```", text)


def test_readme_has_the_two_setup_commands_and_ci_runs_the_test_one():
    install_and_render, install_and_test = readme_commands()
    assert "raycast-phong render" in install_and_render
    assert "pytest" in install_and_test
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    assert ci[-1] == install_and_test


def test_published_json_schema_is_current():
    published = json.loads((ROOT / "docs" / "scene.schema.json").read_text())
    current = json.loads(json.dumps(scene_json_schema()))
    assert published == current, "run: raycast-phong schema > docs/scene.schema.json"


def test_scenes_default_is_the_packaged_default():
    assert (ROOT / "scenes" / "default.toml").read_bytes() == rp.default_scene_path().read_bytes()


def test_scenes_holds_no_symlink_and_the_licence_is_there():
    """Issue 48: scenes/default.toml was a link into the package, dangling when scenes/ was copied alone; the
    project had no licence file."""
    assert not [path for path in (ROOT / "scenes").rglob("*") if path.is_symlink()]
    assert (ROOT / "LICENSE").read_text().startswith("MIT License")


def test_every_example_scene_loads_and_is_documented():
    readme = (ROOT / "README.md").read_text()
    scenes = sorted((ROOT / "scenes").glob("*.toml"))
    assert len(scenes) >= 5
    for path in scenes:
        rp.load_scene(path)
        assert f"`{path.name}`" in readme, f"{path.name} missing from the README's scene table"


def test_benchmark_script_runs_in_a_reduced_form():
    """The benchmark is not a timed test; this keeps the script working (tiny image, one repeat)."""
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_frame.py"), "--size", "64",
                           "--repeats", "1"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert re.search(r"ratio\s+\d+\.\d+", done.stdout)
    assert "64×64, 81,920 triangles" in done.stdout


@pytest.mark.slow
def test_cli_benchmark_runs_in_a_reduced_form():
    """bench_cli.py is not a timed test; this keeps it working (one repeat)."""
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_cli.py"), "--repeats", "1"],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert re.search(r"this tree\s+wall \d+\.\d+ s", done.stdout) and "numba" in done.stdout, done.stdout
    assert "ms  total after Python's own start" in done.stdout, done.stdout


def test_render_benchmark_runs_or_says_how_to_install_open3d(tmp_path):
    """bench_render.py compares with Open3D, which is no dependency: without it (here a package that fails to
    import) one line says how to install it; with it, a tiny run prints the ratio."""
    fake = tmp_path / "open3d"
    fake.mkdir()
    (fake / "__init__.py").write_text("raise ImportError('no open3d here')\n", encoding="utf-8")
    script = str(ROOT / "benchmarks" / "bench_render.py")
    done = subprocess.run([sys.executable, script, "--size", "32", "--repeats", "1"], capture_output=True, text=True,
                          timeout=600, env={**os.environ, "PYTHONPATH": os.pathsep.join(
                              filter(None, (str(tmp_path), os.environ.get("PYTHONPATH"))))})
    assert done.returncode == 1 and "pip install -e '.[bench]'" in done.stderr, done.stderr
    pytest.importorskip("open3d")
    done = subprocess.run([sys.executable, script, "--size", "32", "--repeats", "1"], capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0 and re.search(r"ratio\s+\d+\.\d+", done.stdout), done.stdout + done.stderr


HEAVY = ("numba", "trimesh", "scipy", "embreex")


def test_importing_the_package_the_plugin_and_the_cli_loads_no_renderer():
    """pytest loads the plugin in every session of an environment that has raycast-phong, and --help and
    compare render nothing: none of them may pay the ≈ 0.7 s of numba, trimesh and Embree."""
    probe = (f"import sys, raycast_phong, raycast_phong.pytest_plugin, cli; "
             f"print([m for m in {HEAVY!r} if m in sys.modules])")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert done.stdout.strip() == "[]", done.stdout + done.stderr
    control = subprocess.run([sys.executable, "-c", "import raycast_phong.renderer.frame; " + probe],
                             capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert "'numba'" in control.stdout, control.stdout + control.stderr  # the control: the probe does see one


def test_rendering_built_in_shapes_from_the_cli_loads_no_mesh_library_and_no_tool(tmp_path):
    """A warm `raycast-phong render` pays for what the scene needs: the built-in shapes are numpy, so trimesh
    (≈ 0.2–0.3 s to import) loads only for a mesh file, and the tools only for their own commands."""
    probe = ("import sys\nfrom raycast_phong.cli import app\n"
             "try:\n    app()\nexcept SystemExit as done:\n    assert done.code == 0, done.code\n"
             "print([m for m in sys.modules if m.split('.')[0] == 'trimesh' or m.startswith('raycast_phong.tools')])")
    scene = tmp_path / "shapes.toml"  # one of each built-in shape, tiny
    shapes = ["icosphere", "uv_sphere", "box", "plane", "cylinder", "torus"]
    scene.write_text("[render]\nwidth = 8\nheight = 6\n"
                     + "".join(f'[[objects]]\nshape = "{shape}"\ntranslate = [{3 * i - 7}, 0, 0]\n'
                               for i, shape in enumerate(shapes)), encoding="utf-8")
    done = subprocess.run([sys.executable, "-c", probe, "render", str(scene), "-q", "-o", str(tmp_path / "out.png")],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert done.returncode == 0 and done.stdout.strip() == "[]", done.stdout + done.stderr
    control = subprocess.run([sys.executable, "-c", "import trimesh, raycast_phong.tools.metrics\n" + probe, "--help"],
                             capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert "'trimesh'" in control.stdout and "'raycast_phong.tools.metrics'" in control.stdout, control.stderr


def test_the_package_names_load_on_first_use_and_stay_functions():
    """Importing the submodule raycast_phong.renderer.frame first must not leave the module where render() belongs."""
    probe = ("import sys, raycast_phong.renderer.frame, raycast_phong as rp; "
             "print(callable(rp.render), rp.render.__module__, 'numba' in sys.modules, "
             "set(rp.__all__) <= set(dir(rp)))")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert done.stdout.split() == ["True", "raycast_phong.renderer.frame", "True", "True"], done.stdout + done.stderr
    # load_scene reads any scene file, a mesh file too: its home is mesh_scene, above scene.py (no cycle).
    assert callable(rp.render) and rp.load_scene.__module__ == "raycast_phong.scene.load"


def test_ruff_is_clean():
    """The stated rule set in pyproject.toml ([tool.ruff]) holds over the whole tree; CI runs it through here."""
    ruff = Path(sys.executable).with_name("ruff")
    if not ruff.exists():
        pytest.skip("ruff is not installed in this environment (pip install -e '.[test]' brings it)")
    done = subprocess.run([str(ruff), "check", "--output-format", "concise", str(ROOT)], capture_output=True,
                          text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
