"""Issue 32's leftovers, held: a module keeps its name where it is imported, TOML is written by tomli-w only, and
the memory budget has one home (io.system.budget_of), where a budget of 0 is refused, not made the default."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

import raycast_phong
from raycast_phong.io.scene_toml import toml_value
from raycast_phong.io.system import budget_of

PACKAGE = Path(raycast_phong.__file__).parent


def _modules() -> set[str]:
    return {path.stem for path in PACKAGE.rglob("*.py")} | {path.name for path in PACKAGE.rglob("*") if path.is_dir()}


def test_no_module_is_imported_under_the_name_of_another():
    """`from raycast_phong.tools import study as sweep` read as the sweep module (tools/sweep.py) to a reader."""
    names, wrong = _modules(), []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("raycast_phong")):
                wrong += [f"{path.relative_to(PACKAGE)}: {alias.name} as {alias.asname}" for alias in node.names
                          if alias.asname and alias.name in names and alias.asname in names - {alias.name}]
    assert not wrong


@pytest.mark.parametrize("value", [(1, 0, 0), [(0.5, 1), {"path": "a b.png", "wrap": "clamp"}],
                                   {"x y": [1, {"a": 'q"\n'}]}, "line\nbreak, ]", [], {}, [{"a": 1}],
                                   float("inf"), True])
def test_a_value_is_one_line_of_toml_that_reads_back(value):
    """A tuple (what a Scene holds) was written by the scalar path as tomli-w's multi-line array."""
    text = toml_value(value)
    assert "\n" not in text

    def plain(v):
        if isinstance(v, (list, tuple)):
            return [plain(item) for item in v]
        return {k: plain(item) for k, item in v.items()} if isinstance(v, dict) else v
    assert tomllib.loads(f"v = {text}")["v"] == plain(value)


def test_a_budget_of_zero_is_refused_not_made_the_default(monkeypatch):
    from raycast_phong.io import system as budget
    monkeypatch.setattr(budget, "default_budget", lambda: 12345)  # the memory available moves while tests run
    assert budget_of(None) == 12345
    assert budget_of("1K") == 1024 and budget_of(5000) == 5000
    for nothing in (0, -1, 0.0, False):
        with pytest.raises(ValueError, match="positive number of bytes"):
            budget_of(nothing)


def test_batch_and_compare_ask_budget_of(tmp_path):
    """`max_memory or default_budget()` gave a batch with max_memory=0 the whole default budget."""
    from raycast_phong.tools import batch
    jobs = batch.find_jobs([PACKAGE.parent / "scenes" / "default.toml"])
    with pytest.raises(ValueError, match="positive number of bytes"):
        batch.run_batch(jobs, tmp_path / "out", workers=1, max_memory=0)
    for path in (PACKAGE / "cli" / "compare.py", PACKAGE / "tools" / "batch" / "run.py"):
        assert "default_budget()" not in path.read_text(encoding="utf-8")


# renderer/plan.py is being split by another helper (issue 32 item 5): its build_plan gets its sections there.
WITHOUT_SECTIONS = {"build_plan"}


def test_every_public_function_says_its_parameters_returns_and_raises():
    """Issue 34 item 4: the public names (rp.__all__) document what they take, give and raise."""
    import inspect

    import raycast_phong as rp
    missing = []
    for name in rp.__all__:
        value = getattr(rp, name)
        if inspect.isfunction(value) and name not in WITHOUT_SECTIONS:
            text = inspect.getdoc(value) or ""
            missing += [f"{name}: {word}" for word in ("Parameters", "Returns", "Raises")
                        if word not in text and word.lower().rstrip("s") not in text.lower()]
    assert not missing
