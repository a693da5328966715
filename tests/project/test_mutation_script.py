"""tests/mutation/mutate.py generates sound mutants (the run itself is too slow for the suite: docs/testing.md)."""

from __future__ import annotations

import ast
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("mutate", ROOT / "tests" / "mutation" / "mutate.py")
mutate = importlib.util.module_from_spec(spec)
sys.modules["mutate"] = mutate  # its dataclass looks its module up there
spec.loader.exec_module(mutate)


@pytest.mark.slow
def test_every_mutant_is_a_one_line_edit_that_parses_and_changes_the_code():
    for module in ("renderer/kernels/surface", "renderer/kernels/camera"):  # each has all four kinds
        source = (ROOT / "raycast_phong" / f"{module}.py").read_text(encoding="utf-8")
        lines = source.split("\n")
        mutants = mutate.generate(module)
        assert len(mutants) > 80
        assert {m.kind for m in mutants} >= {"operator", "constant", "drop", "negate"}
        for m in mutants:
            line = lines[m.line - 1]
            assert line[m.col:m.end_col] == m.original
            edited = [*lines[:m.line - 1], line[:m.col] + m.mutated + line[m.end_col:], *lines[m.line:]]
            tree = ast.parse("\n".join(edited))
            assert ast.dump(tree) != ast.dump(ast.parse(source)), m.key


SNIPPET = '''\
from .x import y


@decorate(limit=3)
def f(x: "Annotated[int, 2]" = 1) -> "list[1]":
    """Doc 1."""
    if x > 2:
        raise ValueError(x + 1)
    return x + 1
'''


def test_decorators_annotations_and_raise_statements_are_left_alone():
    mutants = mutate.generate("snippet", SNIPPET)
    assert {m.line for m in mutants} == {5, 7, 9}  # the default, the condition, the returned sum
    assert {m.mutated for m in mutants if m.line == 9} == {"(x - 1)", "(x)", "(1)", "0"}
    assert {m.mutated for m in mutants if m.line == 7} == {"(x >= 2)", "1", "(not x > 2)"}
    assert {m.kind for m in mutants if m.line == 7} == {"compare", "constant", "negate"}


def test_a_node_after_a_wide_character_is_cut_at_its_own_text():
    """ast's column offsets count UTF-8 bytes: a message's "×" before a condition must not shift its span."""
    mutants = mutate.generate("snippet", 'def f(n):\n    return f"{n}×{n}" if n > 1 else ""\n')
    assert "(n >= 1)" in {m.mutated for m in mutants if m.original == "n > 1"}
    for m in mutants:
        ast.parse(m.original, mode="eval")  # each span is a whole expression, not a cut shifted by two bytes


def test_a_set_written_apart_is_read_with_its_reasons():
    """--hand-file's entries carry a fourth element, why the bug is plausible; hand_mutants places each."""
    module = "renderer/budget"
    source = (mutate.REPO / mutate.PACKAGE / f"{module}.py").read_text(encoding="utf-8")
    line = next(t for t in source.splitlines() if t.strip().startswith("def "))
    found = mutate.hand_mutants([(module, line, line + "  # x", "why"), (module, "not there at all", "y", "why")])
    assert [(m.module, m.line, m.kind) for m in found] == [(module, source.splitlines().index(line) + 1, "hand")]


def test_a_set_written_apart_is_listed_without_hand(tmp_path, monkeypatch, capsys):
    """--hand-file alone runs that set: it once needed --hand too, and without it ran every generated mutant of
    the package for hours instead."""
    import json
    module = "renderer/budget"
    source = (mutate.REPO / mutate.PACKAGE / f"{module}.py").read_text(encoding="utf-8")
    line = next(t for t in source.splitlines() if t.strip().startswith("def "))
    (tmp_path / "set.json").write_text(json.dumps([[module, line, line + "  # x", "why"]]), encoding="utf-8")
    monkeypatch.setattr(sys, "argv", ["mutate.py", "--hand-file", str(tmp_path / "set.json"), "--list"])
    mutate.main()
    assert capsys.readouterr().out.strip().splitlines()[-1] == "1 mutants"


def test_the_whole_suite_runs_on_every_core_and_a_subset_in_one_process():
    whole, subset = mutate.pytest_command(["tests"]), mutate.pytest_command(["tests/io", "tests/contracts"])
    assert whole[whole.index("-n") + 1] == "auto" and "-n" not in subset
    for command in (whole, subset):
        assert "-x" in command and "tests/project/test_project.py::test_ruff_is_clean" in command


def test_the_baseline_imports_the_core_package_from_the_copy():
    """The check that a mutant's copy is what gets imported: it once built `import raycast_phong/pipeline`
    from the package path, a syntax error that stopped every mutation run before its first mutant."""
    found = mutate.imported_from(mutate.REPO)
    assert found == str(mutate.REPO / mutate.PACKAGE / "__init__.py"), found


def test_every_module_with_code_is_a_candidate_with_a_subset_that_exists():
    assert {"io/atomic", "renderer/budget", "renderer/kernels/shading", "tools/view/server", "records"} \
        <= set(mutate.MODULES)
    assert "geometry/__init__" not in mutate.MODULES  # empty
    assert set(mutate.CORE_MODULES) <= set(mutate.MODULES)
    for module in mutate.MODULES:
        tests = mutate.tests_for(module)
        assert tests and all((ROOT / path).exists() for path in tests), (module, tests)
    assert mutate.tests_for("renderer/kernels/shading") == ["tests/renderer", "tests/image"]



def test_every_hand_mutant_still_finds_its_text_once():
    """A hand-written bug whose code moved on is silently left out of `--hand` (it prints a line): keep each
    one's original text present exactly once, so the list stays the sample docs/testing.md reports."""
    assert len(mutate.hand_mutants()) == len(mutate.HAND_MUTANTS)
