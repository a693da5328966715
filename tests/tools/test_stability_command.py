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
    assert "non-finite input" in result.stdout and result.stdout.strip().endswith("1 passed, 0 failed")


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
