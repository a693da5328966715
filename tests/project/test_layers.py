"""The package's layers, checked: the oracle stands apart from the code it checks."""

from __future__ import annotations

import json
import subprocess
import sys

# The pipeline stages whose bugs the analytic reference exists to catch: it may import none of them.
STAGES = ("raycast_phong.geometry", "raycast_phong.renderer")


def test_the_oracle_imports_no_stage_of_the_renderer():
    probe = ("import json, sys; import raycast_phong.tools.reference; "
             "print(json.dumps(sorted(m for m in sys.modules "
             "if m.startswith(('raycast_phong.', 'numba', 'embreex')))))")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    loaded = json.loads(done.stdout)
    assert "raycast_phong.tools.reference" in loaded
    stages = [m for m in loaded if m.startswith(STAGES)]  # the kinds (shapes/) load with the schema: data, no stage
    assert not stages and not [m for m in loaded if m.startswith(("numba", "embreex"))], loaded
    assert not {t for t in _package_imports()["tools.reference"] if t.startswith(("geometry", "renderer"))}


def _package_imports() -> dict[str, set[str]]:
    """module → the package modules it imports anywhere in its text (lazy, function-level imports too)."""
    import ast
    from pathlib import Path

    import raycast_phong
    root = Path(raycast_phong.__file__).parent
    graph: dict[str, set[str]] = {}
    for path in root.rglob("*.py"):
        name = ".".join(path.relative_to(root).with_suffix("").parts)
        package = name.rsplit(".", 1)[0] if "." in name else ""
        targets = graph.setdefault(name, set())
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("raycast_phong.")):
                if node.level:
                    base = package.split(".")[:len(package.split(".")) - (node.level - 1)] if package else []
                    stem = ".".join([*filter(None, base), *(node.module.split(".") if node.module else [])])
                else:  # from raycast_phong.x.y import z
                    stem = node.module.removeprefix("raycast_phong.")
                for alias in node.names:
                    for candidate in (f"{stem}.{alias.name}" if stem else alias.name, stem):
                        if candidate and (root / Path(*candidate.split("."))).with_suffix(".py").exists():
                            targets.add(candidate)
                            break
                        if candidate and (root / Path(*candidate.split(".")) / "__init__.py").exists():
                            targets.add(f"{candidate}.__init__")  # a package: its __init__ module
                            break
    graph.pop("__init__", None)
    return {name: {t for t in targets if t != "__init__"} for name, targets in graph.items()}


def test_the_package_has_no_import_cycles():
    """Imports point one way (stages ← tools ← CLI): a cycle means two modules each need the other."""
    graph = _package_imports()
    modules = {"renderer.frame", "tools.reference", "tools.batch.run", "tools.sweep", "renderer.kernels.shading"}
    assert modules <= set(graph)
    state: dict[str, int] = {}
    cycles = []

    def visit(node: str, trail: list[str]) -> None:
        state[node] = 1
        for target in sorted(graph.get(node, ())):
            if state.get(target) == 1:
                cycles.append([*trail[trail.index(target):], target] if target in trail else [node, target])
            elif target not in state:
                visit(target, [*trail, target])
        state[node] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert not cycles, cycles


# The layers, top to bottom, each a folder of the package (base: the modules at its root): a module may import its
# own layer and those below it, never one above. renderer.kernels is the renderer's compiled part: it sees arrays and
# named layouts, never the scene schema. shapes (one module a kind of object: its keys and its triangles) sits below
# the scene, whose schema gathers the kinds' keys from their registry; the kinds declare their keys with the format's
# value types and wording (values), which sit below them.
LAYERS = ("cli", "tools", "renderer", "renderer.kernels", "geometry", "scene", "shapes", "values", "io", "base")
# What compiled code may import from the package.
KERNEL_ALLOWED = {"renderer.kernels.", "tolerances", "codes", "jit", "compiles"}


def _layer(module: str) -> str:
    if "." not in module:
        return "base"  # errors, codes, records, tolerances, jit, compiles, stops
    return "renderer.kernels" if module.startswith("renderer.kernels.") else module.split(".")[0]


def test_imports_point_down_the_layers():
    """cli → tools → renderer → renderer.kernels → geometry → scene → shapes → scene.values → io → base:
    nothing imports upward, and a kernel module imports only other kernel modules, the tolerances, the codes and
    the errors (so an edit to the scene schema or a message recompiles no kernel). The folders show the layers,
    and this keeps them true."""
    graph = _package_imports()
    assert {"renderer.frame", "io.image_io", "tools.batch.run", "renderer.kernels.shading"} <= set(graph)
    order = {layer: rank for rank, layer in enumerate(LAYERS)}
    wrong = set()
    for module, targets in graph.items():
        if module == "pytest_plugin":
            continue
        for target in targets:
            source, goal = _layer(module), _layer(target)
            if goal not in order or source not in order:
                wrong.add(f"{module} -> {target}")  # a module outside every layer
            elif source == "renderer.kernels" and not target.startswith(tuple(KERNEL_ALLOWED)):
                wrong.add(f"{module} -> {target}")
            elif order[goal] < order[source] and not (source == "renderer" and goal == "renderer.kernels"):
                wrong.add(f"{module} -> {target}")
    assert not sorted(wrong), sorted(wrong)


def test_the_pytest_plugin_pulls_in_no_scene_model():
    """Every pytest session of an environment with the package loads the plugin; writing its diagnostics
    (heat map included) must not import pydantic, the scene model or the renderer."""
    probe = ("import json, sys, numpy as np; from pathlib import Path; import tempfile; "
             "from raycast_phong.pytest_plugin import match_images, write_diagnostics; "
             "a = np.zeros((4, 4, 3), np.float32); b = a + 0.5; "
             "write_diagnostics(Path(tempfile.mkdtemp()), 'x', a, b, match_images(a, b)); "
             "print(json.dumps(sorted(m for m in sys.modules if m.startswith(('pydantic', 'raycast_phong.')))))")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    loaded = json.loads(done.stdout)
    assert "raycast_phong.tools.difference" in loaded, done.stderr
    assert not [m for m in loaded if m.startswith("pydantic") or ".scene.schema" in m or ".renderer.frame" in m]


def test_kernel_modules_import_neither_the_scene_schema_nor_pydantic():
    """Loading every kernel module (the tile kernel pulls in all of them) loads no scene schema, no pydantic,
    no record module: the kernels read layout.py's tables, the tolerances and the shared codes (codes.py: the
    model, light and material-column numbers), nothing of the scene."""
    probe = ("import json, sys; from raycast_phong.renderer.kernels import tile, layout, shadows, camera; "
             "print(json.dumps(sorted(m for m in sys.modules if m.startswith(('raycast_phong.', 'pydantic')))))")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    loaded = json.loads(done.stdout)
    assert "raycast_phong.renderer.kernels.tile" in loaded, done.stderr
    outside = [m for m in loaded if not m.startswith(("raycast_phong.renderer.kernels", "raycast_phong.tolerances",
                                                      "raycast_phong.codes", "raycast_phong.jit",
                                                      "raycast_phong.compiles"))
               and m not in ("raycast_phong.renderer", "raycast_phong")]
    assert not outside, outside


def test_each_stage_family_has_one_sequencer_and_the_plan_comes_before_the_geometry():
    """geometry.build is the one function that sequences the geometry stages (grouping, templates, placing, ...):
    no geometry module imports it. The plan is decided before any geometry exists, so renderer.plan imports no
    geometry stage (the kinds' registry, shapes, is data about kinds) and not the diagnosis, which reads
    the plan and the built geometry."""
    graph = _package_imports()
    assert {"geometry.build", "geometry.placing", "renderer.plan", "renderer.diagnosis"} <= set(graph)
    assert not sorted(m for m, targets in graph.items() if m.startswith("geometry.") and "geometry.build" in targets)
    plan = graph["renderer.plan"]
    assert not sorted(t for t in plan if t.startswith("geometry."))
    assert "renderer.diagnosis" not in plan and "renderer.plan" in graph["renderer.diagnosis"]


def _slice_copies(source: str) -> list[str]:
    """Assignments of an array to a slice (`a[i:j] = b[k:l]`) inside the @kernel functions of `source`; a slice
    filled with a constant (`a[:] = 0`) is not one."""
    import ast
    found = []
    for node in ast.walk(ast.parse(source)):
        if not (isinstance(node, ast.FunctionDef) and any(
                isinstance(d, ast.Call) and getattr(d.func, "id", None) == "kernel" for d in node.decorator_list)):
            continue
        for assign in ast.walk(node):
            if not isinstance(assign, ast.Assign) or isinstance(assign.value, (ast.Constant, ast.UnaryOp)):
                continue
            for target in assign.targets:
                for sub in ast.walk(target):
                    parts = sub.slice.elts if isinstance(sub, ast.Subscript) and isinstance(sub.slice, ast.Tuple) \
                        else [sub.slice] if isinstance(sub, ast.Subscript) else []
                    if any(isinstance(part, ast.Slice) for part in parts):
                        found.append(f"{node.name} line {assign.lineno}: {ast.unparse(assign)}")
    return found


def test_no_kernel_copies_an_array_into_a_slice():
    """numba compiles a slice assignment's shape-mismatch message (str, repr, concatenation): 2-2.5 s of a first
    compile each (docs/performance.md); the plain OBJ scan's one made its compile 3.3 s of CPU instead of 1.3.
    Kernels copy with loops. The check itself: it finds the copy it is meant to find."""
    from pathlib import Path
    assert _slice_copies("@kernel()\ndef f(a, b):\n    a[1:3] = b[0:2]\n    a[:] = 0\n") == [
        "f line 3: a[1:3] = b[0:2]"]
    package = Path(__file__).resolve().parents[2] / "raycast_phong"
    found = [f"{path.relative_to(package)}: {line}" for path in sorted(package.rglob("*.py"))
             for line in _slice_copies(path.read_text(encoding="utf-8"))]
    assert not found, found
