"""`continuum-sim validate --quick`: every row of the quick report passes, and the CLI writes it."""

import json

from continuum_sim.cli import main
from continuum_sim.validation.report import (
    CHECKS,
    Check,
    Row,
    all_checks,
    run_checks,
    write_report,
)


def test_quick_report_rows_all_pass(tmp_path):
    """The quick subset of every registered check (the suite's share of the full report)."""
    report = run_checks(quick=True)
    assert not report.errors, report.errors
    failing = [f"{r.check}: {r.quantity} = {r.measured} (tolerance {r.tolerance})" for r in report.rows if not r.passed]
    assert not failing, failing
    names = {r.check for r in report.rows}
    for expected in (
        "cosserat.analytic",
        "sorosim.dynamics.steel",
        "sorosim.dynamics.tpu",
        "sorosim.statics",
        "tendon.section2",
        "modes.section2",
    ):
        assert expected in names
    paths = write_report(report, tmp_path, plots=False)
    data = json.loads((tmp_path / "report.json").read_text())
    assert data["passed"] and len(data["rows"]) == len(report.rows)
    assert "| check | reference | quantity | tolerance | measured | result | reproduce |" in paths[0].read_text()


def test_cli_validate_only_writes_the_report(tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["validate", "--quick", "--only", "cosserat.beam", "--no-plots", "--out", str(out)]) == 0
    assert (out / "report.md").is_file() and (out / "report.json").is_file()
    assert "cosserat.beam" in capsys.readouterr().out


def test_cli_validate_unknown_check_is_a_one_line_error(tmp_path, capsys):
    assert main(["validate", "--only", "no.such.check", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--only" in err and "no.such.check" in err


def test_a_failing_or_raising_check_fails_the_report(monkeypatch):
    """A row over its tolerance and a check that raises both make the report fail (exit 1)."""

    def bad(quick: bool) -> list[Row]:
        return [Row("x.bad", "ref", "q", "≤ 1 %", "2 %", False, 2.0, 1.0)]

    def broken(quick: bool) -> list[Row]:
        raise RuntimeError("boom")

    monkeypatch.setattr("continuum_sim.validation.report.CHECKS", [Check("x.bad", "r", bad), Check("x.broken", "r", broken)])
    report = run_checks(quick=True)
    assert not report.passed
    assert report.errors == {"x.broken": "RuntimeError: boom"}
    assert "**FAIL**" in report.markdown() and "**ERROR**" in report.markdown()


def test_registry_names_are_unique():
    names = [c.name for c in all_checks()]
    assert len(names) == len(set(names)) and len(CHECKS) >= 10
