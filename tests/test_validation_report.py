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


def test_quick_report_states_the_full_reports_status(tmp_path):
    """A quick run's header carries the committed full report's verdict, and its default folder is not the committed one."""
    from continuum_sim.validation.report import COMMITTED_REPORT, QUICK_OUT, full_report_status, full_status_line

    full = json.loads((COMMITTED_REPORT / "report.json").read_text())
    failing = sorted({r["check"] for r in full["rows"] if not r["passed"]})
    status = full_report_status(quick_checks=["cosserat.beam"], quick_failing=[])
    assert status["rows"] == len(full["rows"]) and status["rows_passed"] == sum(r["passed"] for r in full["rows"])
    assert status["failing_checks"] == failing and status["not_reproduced"] == failing
    line = full_status_line(status)
    assert f"{status['rows_passed']}/{status['rows']} rows pass" in line
    if failing:
        assert "reproduces none of them" in line and failing[0] in line
    # a fake full report with nothing failing: the line says so and nothing more
    clean = tmp_path / "report.json"
    clean.write_text(json.dumps({"rows": [{"check": "a.b", "passed": True}], "errors": {}}))
    assert full_status_line(full_report_status(clean)).endswith("1/1 rows pass.")
    assert "not available" in full_status_line(full_report_status(tmp_path / "missing.json"))
    assert QUICK_OUT.startswith("runs/")


def test_cli_quick_never_writes_the_committed_report(tmp_path, capsys, monkeypatch):
    from continuum_sim.validation.report import COMMITTED_REPORT

    assert main(["validate", "--quick", "--only", "cosserat.beam", "--no-plots", "--out", str(COMMITTED_REPORT)]) == 2
    assert "committed full report" in capsys.readouterr().err
    monkeypatch.chdir(tmp_path)  # the default folder, relative to where it runs
    assert main(["validate", "--quick", "--only", "cosserat.beam", "--no-plots"]) == 0
    text = (tmp_path / "runs" / "validation-quick" / "report.md").read_text()
    assert "**Full report**" in text.splitlines()[4] or "**Full report**" in text
    data = json.loads((tmp_path / "runs" / "validation-quick" / "report.json").read_text())
    assert data["full_report"]["available"] is True


def test_printed_summary_fits_100_columns_and_explains_known_failures():
    """``validate`` prints a table no wider than 100 columns, and the full report's failing families in context."""
    from continuum_sim.validation.report import CONSOLE_WIDTH, Report, full_report_status

    long = "a quantity whose description is much longer than any terminal column would comfortably hold " * 2
    rows = [Row("tendon.section0", "Cosserat tendon model, section 0 (physical disks, hinge_pair), τ ≤ 1·120.4 N, "
                "15 tension sets × 3 gravity", long, "≤ 1 % L", "4.119 % L", False, 4.1, 1.0),
            Row("cosserat.beam", "Euler–Bernoulli small deflection", "tip force: δ vs F·L³/3EI", "≤ 0.1 %",
                "-1.14e-07 %", True, 0.0, 0.1)]
    report = Report(True, rows=rows, errors={"x.broken": "RuntimeError: " + "boom " * 40})
    report.full_status = full_report_status(quick_checks=["cosserat.beam"], quick_failing=["tendon.section0"])
    text = report.console(report_md="runs/validation-quick/report.md")
    assert CONSOLE_WIDTH == 100
    assert all(len(line) <= 100 for line in text.splitlines()), max(text.splitlines(), key=len)
    assert "FAIL" in text and "ERROR" in text and "**" not in text
    assert "Known failures" in text and "docs/validation.md" in text
    assert "Not a known failure: x.*" in text  # a failing family nobody explained is called out
