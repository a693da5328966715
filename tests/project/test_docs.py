"""The docs cannot drift from the code: their Python examples run, and every name they give exists.

1. The README's and docs/'s ```python blocks, and the package docstrings' indented examples that use
   `raycast_phong`, run in a temporary folder holding `scenes/` and the mesh files the examples name
   (model.obj, model.glb). A block that needs something else says so in its first line: `# docs: skip`.
2. Every backticked `module.name` (module: a module or subpackage of raycast_phong, or `rp`) and every
   backticked path (`io/atomic.py`, `tests/io/`, a bare `jit.py`; not a user's `a.toml`) in README.md and
   docs/*.md, outside fenced blocks, resolves to an attribute, a scene key or a file of the repository.
"""

from __future__ import annotations

import ast
import importlib
import os
import re
import typing
from pathlib import Path

import pytest

import raycast_phong

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "raycast_phong"
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SKIP = "# docs: skip"

# Names in docs/pipeline.md's module tree, which is rewritten as a whole after the package's reorganisation
# (issue 19). Like tests/project/test_layers.py's PENDING, this set must only shrink.
PENDING: set[tuple[str, str]] = set()


def _fenced_python(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, re.S | re.M)


def _docstring_examples() -> list[tuple[str, str]]:
    """(where, code) for each indented block of a package docstring that parses as Python and uses the package."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Module, ast.FunctionDef, ast.ClassDef)):
                continue
            doc = ast.get_docstring(node)
            for block in re.findall(r"(?:^|\n\n)((?:    .*(?:\n|$))+)", doc or ""):
                code = "\n".join(line[4:] for line in block.splitlines())
                try:
                    ast.parse(code)
                except SyntaxError:
                    continue
                if "raycast_phong" in code:
                    found.append((f"{path.relative_to(ROOT)}:{getattr(node, 'name', 'module')}", code))
    return found


EXAMPLES = [(f"{path.name}#{i}", code) for path in DOCS for i, code in enumerate(_fenced_python(path.read_text()))]
EXAMPLES += _docstring_examples()


@pytest.fixture(scope="module")
def example_folder(tmp_path_factory):
    """scenes/ (a link to the repository's) and small mesh files named model.obj and model.glb."""
    import trimesh
    folder = tmp_path_factory.mktemp("examples")
    (folder / "scenes").symlink_to(ROOT / "scenes")
    sphere = trimesh.creation.icosphere(subdivisions=1)
    for name in ("model.obj", "model.glb"):
        sphere.export(folder / name)
    return folder


def test_the_examples_are_found():
    """The control for the test below: it sees the README's example and the package docstring's."""
    names = [where for where, _ in EXAMPLES]
    assert "README.md#0" in names and "raycast_phong/__init__.py:module" in names, names


@pytest.mark.parametrize(("where", "code"), EXAMPLES, ids=[where for where, _ in EXAMPLES])
def test_the_python_examples_run(where, code, example_folder, monkeypatch):
    if code.lstrip().startswith(SKIP):
        pytest.skip(code.lstrip().splitlines()[0])
    monkeypatch.chdir(example_folder)
    small = ["render.width=16", "render.height=12"]
    load, render_file = raycast_phong.load_scene, raycast_phong.render_file
    # The examples render at their scenes' sizes; 16 × 12 runs the same calls in a fraction of the time.
    monkeypatch.setattr(raycast_phong, "load_scene",
                        lambda path, overrides=(), **kw: load(path, [*overrides, *small], **kw))
    monkeypatch.setattr(raycast_phong, "render_file",
                        lambda path, overrides=(), **kw: render_file(path, [*overrides, *small], **kw))
    exec(compile(code, where, "exec"), {"raycast_phong": raycast_phong, "__name__": "example"})


# ---------------------------------------------------------------- names


def _modules() -> dict[str, list[str]]:
    """Last component → the dotted names of the package's modules and subpackages that end in it."""
    found: dict[str, list[str]] = {"raycast_phong": ["raycast_phong"], "rp": ["raycast_phong"]}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found.setdefault(parts[-1], []).append(".".join(parts))
    return found


MODULES = _modules()


def _resolves(dotted: str) -> bool:
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            value = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for name in parts[cut:]:
                value = getattr(value, name)
        except AttributeError:
            return False
        return True
    return False


def _models_in(annotation) -> list:
    """Every pydantic model an annotation holds: itself, a tuple's or a dict's items, each kind of a union."""
    if hasattr(annotation, "model_fields"):
        return [annotation]
    return [model for argument in typing.get_args(annotation) for model in _models_in(argument)]


def _is_scene_key(token: str) -> bool:
    """A key path of the scene format; an upper-case placeholder or a digit stands for any entry of a table of
    named entries ([materials.NAME]) or any item of a list ([[objects]], whose items are of several kinds)."""
    from raycast_phong.scene.schema import Scene
    models, entries = [Scene], False
    for name in token.split("."):
        if entries:
            entries = False
            if name.isupper() or name.isdigit():
                continue
        found = [model.model_fields[name] for model in models if name in model.model_fields]
        if not found:
            return False
        entries = any(typing.get_origin(field.annotation) in (dict, tuple) for field in found)
        models = [model for field in found for model in _models_in(field.annotation)]
    return True


def _file_exists(token: str) -> bool:
    if token.startswith("../"):
        return False  # outside the repository: a reader of the package cannot follow it
    token = token.rstrip("/")
    if any((folder / name).exists() for folder in (ROOT, PACKAGE) for name in (token, f"{token}.py")):
        return True
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if not d.startswith(".") and d not in ("build", "__pycache__")]
        if any(Path(folder, name).as_posix().endswith("/" + token) for name in [*dirs, *files]):
            return True
    return False


ROOTS = {"raycast_phong", "tests", "docs", "scenes", "benchmarks", ".ci",
         *{p.name for p in PACKAGE.rglob("*") if p.is_dir() and p.name != "__pycache__"}}


FILES = (".py", ".toml", ".json", ".md", ".ply", ".obj", ".glb", ".mtl", ".js", ".css", ".html", ".csv", ".png",
         ".exr")  # a `name.toml` is a file, not an attribute


def names_in(text: str) -> list[str]:
    """The backticked names and paths to check in one Markdown text (fenced blocks left out)."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    names = []
    for token in re.findall(r"`([^`\n]+)`", text):
        token = token.split("(")[0].strip()
        if re.fullmatch(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)+", token, re.A) and not token.endswith(FILES):
            if token.split(".")[0] in MODULES:
                names.append(token)
        elif re.fullmatch(r"[\w.-]+(/[\w.-]+)*/?", token, re.A) and (
                token.endswith(".py") or ("/" in token and token.split("/")[0] in {*ROOTS, ".."})):
            names.append(token)
    return names


def unresolved(token: str) -> bool:
    if "/" in token or token.endswith(FILES):
        return not _file_exists(token)
    first, rest = token.split(".", 1)
    if _is_scene_key(token):
        return False
    return not any(_resolves(f"{module}.{rest}") for module in MODULES[first])


def test_the_name_check_sees_a_wrong_name():
    """The control: a misspelt function, a module's old home and a missing file are caught."""
    text = "`accuracy.refined` `reference.refined` `pipeline/render.py` `camera.position` `io/atomic.py` `io/atomic`"
    assert [t for t in names_in(text) if unresolved(t)] == ["reference.refined", "pipeline/render.py"]


def test_every_name_in_the_docs_exists():
    wrong = {(path.name, token) for path in DOCS for token in names_in(path.read_text()) if unresolved(token)}
    assert not sorted(wrong - PENDING), sorted(wrong - PENDING)
    assert not sorted(PENDING - wrong), "fixed: remove from PENDING " + str(sorted(PENDING - wrong))


# A commit id: 7 to 40 hex digits holding a digit and a letter a-f (so neither "decade" nor "1000000" is one). A
# clock time: two-digit hours and minutes (09:16, 23:42–23:47), not an aspect ratio (16:9) or a range of scores.
COMMIT = re.compile(r"(?<![\w#./-])(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}(?![\w-])")
CLOCK = re.compile(r"(?<![\d:.])(?:[01]\d|2[0-3]):[0-5]\d(?::[0-5]\d)?(?![\d:])")
DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")


def _diary(text: str) -> list[str]:
    """What a reference has no use for: commit ids, clock times and dates, outside fenced blocks (a how-to may print
    a hash)."""
    prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return [found.group() for pattern in (COMMIT, CLOCK, DATE) for found in pattern.finditer(prose)]


def test_the_diary_check_sees_a_commit_id_a_clock_time_and_a_date():
    """The control: the words a session's diary leaves."""
    assert _diary("measured at 016e3ef (09:16 and 23:42–23:47 UTC, 2026-12-03)") == \
        ["016e3ef", "09:16", "23:42", "23:47", "2026-12-03"]
    assert _diary("a 16:9 frame, 1000000 boxes, a decade, bunny-1m, sha256 in `x.py`, 1:1, 12:345") == []


def test_the_docs_are_a_reference_not_a_diary():
    """docs/*.md say what holds now and how to re-measure it: how a figure was reached belongs in a commit message
    (issue 44: 23 commit ids and 4 clock times had crept back)."""
    found = {path.name: _diary(path.read_text(encoding="utf-8")) for path in DOCS}
    assert not {name: words for name, words in found.items() if words}


FORMAT_COLUMNS = ["format", "suffixes", "geometry", "normals", "UVs", "vertex colours", "materials", "textures",
                  "up axis", "noted (the render goes on)", "refused (exit 2)"]


def _tables(text: str) -> list[tuple[int, list[list[str]]]]:
    """(first line's index, rows of cells) of each Markdown table outside fenced blocks; the separator row left out."""
    tables, fenced, current = [], False, None
    for index, line in enumerate(text.splitlines()):
        fenced ^= line.startswith("```")
        if not fenced and line.startswith("|"):
            if current is None:
                current = (index, [])
                tables.append(current)
            cells = [cell.strip() for cell in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
            if not all(re.fullmatch(r":?-+:?", cell) for cell in cells):
                current[1].append(cells)
        else:
            current = None
    return tables


def test_performance_is_a_page_and_meshes_opens_with_its_formats():
    """performance.md stays a page a reader reads (it had grown to 415 lines of dated tables). meshes.md's first
    table, before any example or second section, is the formats table, with a row for every format of the registry
    holding each of its suffixes."""
    from raycast_phong.io.meshes import FORMATS
    assert len((ROOT / "docs" / "performance.md").read_text(encoding="utf-8").splitlines()) <= 300
    text = (ROOT / "docs" / "meshes.md").read_text(encoding="utf-8")
    (start, rows), *_ = _tables(text)
    before = text.splitlines()[:start]
    assert not any(line.startswith("```") for line in before), "an example comes before the formats table"
    assert sum(line.startswith("## ") for line in before) <= 1, "a second section comes before the formats table"
    header, *body = rows
    assert header == FORMAT_COLUMNS, header
    suffixes = {suffix for row in body for suffix in re.findall(r"`(\.\w+)`", row[1])}
    for kind in FORMATS:
        assert set(kind.suffixes) <= suffixes, f"{kind.names[0]}: {kind.suffixes} not in the formats table"


def test_every_test_the_specification_table_names_exists():
    """docs/meshes.md's "What each specification says" names the test holding each rule: each exists (a renamed
    or deleted test would leave the row unproven)."""
    text = (ROOT / "docs" / "meshes.md").read_text(encoding="utf-8")
    section = text.split("## What each specification says", 1)[1].split("\n## ", 1)[0]
    named = re.findall(r"`(tests/[\w/]+\.py)::(\w+)`", section)
    assert len(named) >= 25, named
    for path, name in named:
        source = (ROOT / path).read_text(encoding="utf-8")
        assert re.search(rf"^def {name}\(", source, re.M), f"{path}::{name} is named in docs/meshes.md but not defined"


def _pipeline_tree() -> str:
    """docs/pipeline.md up to the end of its first fenced block: the layers' table and the layout, module by
    module."""
    text = (ROOT / "docs" / "pipeline.md").read_text(encoding="utf-8")
    return re.search(r"\A.*?^```\n.*?^```", text, re.S | re.M).group(0)


def _unnamed_modules(tree: str) -> list[str]:
    """The package's modules (not `__init__`, `__main__`) whose file name the layout never gives."""
    named = set(re.findall(r"\b(\w+)\b", tree))
    return sorted(str(path.relative_to(PACKAGE)) for path in PACKAGE.rglob("*.py")
                  if path.stem not in ("__init__", "__main__") and path.stem not in named)


def test_the_pipeline_layout_names_every_module():
    """A newcomer finds a module from pipeline.md's tree: a module added without its line there fails here (six had
    drifted out of it, and four were never in it)."""
    tree = _pipeline_tree()
    assert _unnamed_modules(tree) == []
    assert _unnamed_modules(tree.replace("keypaths", "")) == ["scene/keypaths.py"]  # the check sees a gap
