"""`raycast-phong stability`: the table, --json, --case, and exit status 1 when a case fails."""

import json

from typer.testing import CliRunner

from raycast_phong.cli import app
from raycast_phong.tools import stability

runner = CliRunner()


def test_json_for_chosen_cases():
    result = runner.invoke(app, ["stability", "--json", "--case", "watertightness", "--case", "grazing_light"])
    assert result.exit_code == 0, result.output
    rows = json.loads(result.stdout)
    assert [row["case"] for row in rows] == ["watertightness", "grazing light"]
    assert all(row["passed"] is True and "miss" in rows[0]["figure"] for row in rows)


def test_table_ends_with_the_counts():
    result = runner.invoke(app, ["stability", "--case", "non_finite_input"])
    assert result.exit_code == 0
    assert "non-finite" in result.stdout and result.stdout.strip().endswith("1 passed, 0 failed")


def test_a_failing_case_exits_1(monkeypatch):
    monkeypatch.setitem(stability.CASES, "non_finite_input",
                        lambda: stability.CaseResult("broken", "cannot hold", "0 of 1", False))
    result = runner.invoke(app, ["stability", "--case", "non_finite_input"])
    assert result.exit_code == 1
    assert "0 passed, 1 failed" in result.stdout


def test_unknown_case_is_bad_input():
    result = runner.invoke(app, ["stability", "--case", "nope"])
    assert result.exit_code == 2 and "unknown case 'nope'" in result.output


def test_list_names_every_case():
    result = runner.invoke(app, ["stability", "--list"])
    assert result.stdout.split() == list(stability.CASES)


def test_every_measured_case_gives_its_number_and_the_limit_it_was_checked_against():
    """A referee's question (issue 47): the value, the limit and the margin, in the table and in --json. Only
    yes-or-no properties (a warning given) have none; a passing case's margin is at least 1."""
    result = runner.invoke(app, ["stability", "--json"])
    rows = json.loads(result.stdout)
    qualitative = {"sub-pixel highlight"}
    for row in rows:
        if row["case"] in qualitative:
            continue
        assert isinstance(row["value"], (int, float)) and isinstance(row["limit"], (int, float)), row
        assert row["margin"] is None or not row["passed"] or row["margin"] >= 1, row
    assert sum(row["value"] is not None for row in rows) >= len(rows) - len(qualitative)


def test_the_table_fits_an_80_column_terminal_with_its_words_whole():
    """Below 120 columns (and piped: 80) a block a case, wrapped between words; the table broke them ("propert y")
    and left two headers unnamed."""
    result = runner.invoke(app, ["stability", "--case", "far_camera", "--case", "grazing_light"],
                           env={"COLUMNS": "80", "NO_COLOR": "1"})
    lines = result.stdout.splitlines()
    assert max(len(line) for line in lines) <= 80 and lines[0].startswith("far camera: pass (0.000"), result.stdout
    assert "≤ 0.01, margin" in lines[0] and "\x1b" not in result.stdout
    words = " ".join(lines).split()
    property_ = stability.CASES["far_camera"]().property
    assert all(word in words for word in property_.split()), (property_, result.stdout)


def test_the_margin_is_the_limit_over_the_value():
    row = stability.CaseResult("c", "p", "f", True, value=0.25, limit=1.0)
    assert row.margin == 4.0
    assert stability.CaseResult("c", "p", "f", True, value=6, limit=3, at_least=True).margin == 2.0
    assert stability.CaseResult("c", "p", "f", True, value=0.0, limit=1.0).margin == float("inf")


def test_run_all_reports_each_case_before_it_runs_and_done_after_the_last(monkeypatch):
    """progress(done, total, next case) before each case, then (total, total, "done"): a bar that ends full."""
    monkeypatch.setitem(stability.CASES, "non_finite_input", lambda: stability.CaseResult("c", "p", "f", True))
    calls = []
    results = stability.run_all(["non_finite_input", "non_finite_input"], lambda *call: calls.append(call))
    assert calls == [(0, 2, "non_finite_input"), (1, 2, "non_finite_input"), (2, 2, "done")]
    assert [row.passed for row in results] == [True, True]


def test_non_finite_input_fails_when_one_field_slips_through(monkeypatch):
    """Every one of the 7 inputs must be refused naming its key: a NaN ambient accepted leaves 6 of 7, a failure."""
    real = stability.validate_scene
    monkeypatch.setattr(stability, "validate_scene",
                        lambda data, **keys: None if "ambient" in data else real(data, **keys))
    row = stability.non_finite_input()
    assert (row.passed, row.value, row.limit, row.figure) == (False, 6, 7, "6 of 7 refused with the key named")


def test_json_gives_an_infinite_margin_as_null_so_the_output_stays_json(monkeypatch):
    """A value of 0 under its limit is infinitely within it: --json writes null there (JSON has no Infinity)."""
    monkeypatch.setitem(stability.CASES, "non_finite_input",
                        lambda: stability.CaseResult("zero", "p", "0", True, value=0.0, limit=1.0))
    result = runner.invoke(app, ["stability", "--json", "--case", "non_finite_input"])
    assert result.exit_code == 0, result.output
    assert "Infinity" not in result.stdout
    assert json.loads(result.stdout)[0]["margin"] is None
