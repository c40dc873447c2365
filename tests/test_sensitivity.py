"""Sensitivity studies: spec checks, a tiny Morris study end to end, kill and resume, Sobol' on a known function."""

from __future__ import annotations

import csv
import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from continuum_sim.configio import ConfigError
from continuum_sim.sensitivity import load_spec, parse_spec, run_study
from continuum_sim.sensitivity.design import analyze_sobol, sample_matrix
from continuum_sim.sensitivity.study import study_sweep

ROOT = Path(__file__).resolve().parents[1]

# Cheap: 2 parameters, r = 2 (6 rows), the static gravity-sag hold settled for 0.2 s (~0.3 s CPU each).
TINY = """\
method = "morris"
parameters = ["model.joint_damping", "arm.material.youngs_modulus"]
metrics = ["sag_mm", "max_cable_tension_n"]

[morris]
trajectories = 2

[evaluation]
kind = "gravity_sag"
settle_s = 0.2
"""


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('parameters = ["model.cable_friction.muu"]', "parameters[0]: model.cable_friction.muu: not a registry parameter"),
        ('parameters = ["arm.sections.0.length"]', "has no plausible range in the registry"),
        ('method = "fast"\nparameters = ["model.cable_friction.mu"]', "method: must be one of morris, sobol"),
        ('parameters = ["model.cable_friction.mu"]\n[morris]\nlevels = 3', "morris.levels: must be even"),
        ('parameters = ["model.cable_friction.mu"]\n[ranges]\n"model.cable_friction.mu" = [0.3, 0.1]', "must satisfy low < high"),
        ('parameters = ["model.joint_damping"]\n[ranges]\n"model.joint_damping" = [0.0, 1.0]', "sampled logarithmically"),
        ('parameters = ["model.cable_friction.mu", "plan.cut_speed"]\nmethod = "sobol"\n[sobol]\nsamples = 48', "power of 2"),
        ('parameters = ["model.cable_friction.mu"]\n[config.control]\nmode = "half"', "config.control.mode"),
        ('parameters = ["model.cable_friction.mu"]\nextra = 1', "extra: unknown key"),
    ],
)
def test_spec_errors_name_the_field(text, message):
    import tomllib

    with pytest.raises(ConfigError) as info:
        parse_spec(tomllib.loads(text))
    assert message in str(info.value)


def test_spec_cli_error_is_one_line_exit_2(tmp_path):
    spec = tmp_path / "bad.toml"
    spec.write_text('parameters = ["model.cable_friction.mu"]\n[ranges]\n"model.cable_friction.mu" = [0.5]\n')
    proc = subprocess.run([sys.executable, "-m", "continuum_sim", "sensitivity", str(spec), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "ranges.model.cable_friction.mu: must be [low, high]" in proc.stderr
    assert not (tmp_path / "o").exists()


def test_samples_respect_ranges_and_log_scale():
    import tomllib

    spec = parse_spec(tomllib.loads('parameters = ["model.cable_friction.presliding", "model.cable_friction.mu"]\n'
                                    "[morris]\ntrajectories = 10\n"))
    sweep, rows = study_sweep(spec)
    assert len(rows) == 30
    values = np.array([[v for _, v in variant.params] for variant in sweep.samples])
    assert values[:, 0].min() == pytest.approx(1e-4) and values[:, 0].max() == pytest.approx(3e-3)
    # 4 levels of a log range: geometric steps (1e-4, 3.1e-4, 9.7e-4, 3e-3), not linear ones
    levels = np.unique(np.round(np.log10(values[:, 0]), 9))
    assert np.allclose(np.diff(levels), np.diff(levels)[0])
    assert set(np.round(values[:, 1], 12)) <= {0.0, 0.1, 0.2, 0.3}
    again, _ = study_sweep(spec)  # same seed, same samples: what resuming relies on
    assert [v.variant_id for v in again.samples] == [v.variant_id for v in sweep.samples]


def test_sobol_indices_of_a_known_function():
    """y = x0 + 2·x1 on [0, 1]²: S1 = 1/5 and 4/5 (variances 1/12 and 4/12), no interaction."""
    import tomllib

    spec = parse_spec(tomllib.loads('method = "sobol"\nparameters = ["model.cable_friction.mu", "plan.cut_speed"]\n'
                                    '[ranges]\n"model.cable_friction.mu" = [0.0, 1.0]\n"plan.cut_speed" = [0.0, 1.0]\n'
                                    "[sobol]\nsamples = 1024\n"))
    x = sample_matrix(spec)
    indices = analyze_sobol(spec, x[:, 0] + 2.0 * x[:, 1])["indices"]
    assert indices["model.cable_friction.mu"]["S1"] == pytest.approx(0.2, abs=0.03)
    assert indices["plan.cut_speed"]["S1"] == pytest.approx(0.8, abs=0.03)
    assert indices["plan.cut_speed"]["ST"] == pytest.approx(0.8, abs=0.03)


def _records(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in (out / "records").glob("*.json")}


def test_tiny_study_end_to_end_and_resume_after_kill(tmp_path):
    spec_path = tmp_path / "tiny.toml"
    spec_path.write_text(TINY)
    spec = load_spec(spec_path)
    out = tmp_path / "study"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "continuum_sim", "sensitivity", str(spec_path), "--out", str(out), "--workers", "1", "--quiet"]
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and proc.poll() is None and len(_records(out)) < 2:
            time.sleep(0.02)
        assert proc.poll() is None, "the study finished before it could be killed"
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    before = _records(out)
    assert len(before) >= 2

    result = run_study(spec, out, workers=2, progress=False)
    assert result.n_skipped == len(before) and result.n_run == result.n_distinct - len(before) and result.n_failed == 0
    after = _records(out)
    for name, data in before.items():  # recorded before the kill: kept, not re-evaluated
        assert after[name] == data
    assert len(after) == result.n_distinct

    summary = json.loads((out / "summary.json").read_text())
    assert summary["rows"] == 6 and summary["rows_recorded"] == 6 and summary["method"] == "morris"
    sag = summary["analysis"]["sag_mm"]
    assert sag["trajectories_used"] == 2
    assert sag["indices"]["arm.material.youngs_modulus"]["mu_star"] > 0.0
    assert set(summary["strongest"]) == {"model.joint_damping", "arm.material.youngs_modulus"}
    with (out / "indices.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 4 and {r["metric"] for r in rows} == {"sag_mm", "max_cable_tension_n"}
    with (out / "samples.csv").open() as fh:
        samples = list(csv.DictReader(fh))
    assert len(samples) == 6 and all(r["status"] == "ok" and r["sag_mm"] for r in samples)
    assert (out / "plots" / "indices.png").stat().st_size > 0 and (out / "plots" / "outcome_map.png").stat().st_size > 0
    assert any("r = 2 trajectories" in w and "r = 10 would do (30 runs" in w for w in summary["warnings"])  # r < 10: said, with the size
    assert "**Warning:** Morris r = 2" in (out / "summary.md").read_text()
    if importlib.util.find_spec("pyarrow") is not None:  # the Parquet table equals the CSV
        import pyarrow.parquet as pq

        table = pq.read_table(out / "samples.parquet").to_pydict()
        assert table["variant_id"] == [r["variant_id"] for r in samples]
        assert table["sag_mm"] == [float(r["sag_mm"]) for r in samples] and "samples.parquet" in summary["files"]
    else:
        assert summary["notes"] and "pyarrow" in summary["notes"][0]

    rerun = run_study(spec, out, workers=1, progress=False)  # nothing left to evaluate
    assert rerun.n_run == 0

    changed = tmp_path / "changed.toml"
    changed.write_text(TINY.replace("trajectories = 2", "trajectories = 3"))
    with pytest.raises(ConfigError, match="holds a different sweep"):
        run_study(load_spec(changed), out, workers=1, progress=False)


@pytest.mark.parametrize("name", sorted(p.name for p in (ROOT / "studies").glob("sensitivity_*.toml")))
def test_shipped_specs_are_valid(name):
    """Every shipped study parses, uses registry ranges, and every sample's configuration validates."""
    from continuum_sim.sensitivity.study import check_samples

    spec = load_spec(ROOT / "studies" / name)
    assert spec.base.control.mode in ("open", "closed") and spec.evaluation.kind == "scenario"
    sweep, rows = study_sweep(spec)
    assert len(rows) >= 28
    check_samples(sweep, limit=3)  # the study checks every sample before it starts


def test_bad_out_is_refused_before_work(tmp_path, capsys):
    from continuum_sim.cli import main

    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY)
    afile = tmp_path / "a_file"
    afile.write_text("x")
    assert main(["sensitivity", str(spec), "--out", str(afile)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--out" in err and "not a folder" in err


# --- the uncertainty method (success probability over the ranges) ------------------------------------------


def _uncertainty_spec(**extra):
    from continuum_sim.sensitivity.spec import parse_spec

    data = {"method": "uncertainty", "parameters": ["model.cable_friction.mu", "model.rope_modulus"],
            "uncertainty": {"samples": 8, "seed": 1}, "success": {"cut_path_deviation_mm.mean": {"max": 2.5}},
            "evaluation": {"kind": "scenario"}, **extra}
    return parse_spec(data)


def test_uncertainty_spec_samples_a_latin_hypercube_and_adds_the_outcome_metrics():
    from continuum_sim.sensitivity.design import sample_matrix, sample_params
    from continuum_sim.sensitivity.spec import n_evaluations

    spec = _uncertainty_spec()
    assert spec.metrics[:3] == ("task.completed", "task.failure", "cut_path_deviation_mm.mean")
    assert n_evaluations(spec) == 8
    matrix = sample_matrix(spec)
    assert matrix.shape == (8, 2)
    # Latin hypercube: each parameter has exactly one sample in each of the 8 equal strata of its range
    for j, factor in enumerate(spec.factors):
        lo, hi = factor.bounds
        strata = np.floor((matrix[:, j] - lo) / (hi - lo) * 8).astype(int)
        assert sorted(strata.tolist()) == list(range(8))
    assert (sample_matrix(spec) == matrix).all()  # a pure function of the spec: a resumed study finds its records
    assert len(sample_params(spec, matrix)) == 8


def test_uncertainty_spec_refuses_bad_success_tables():
    from continuum_sim.configio import ConfigError

    for bad, field in (({"success": {"x": 2.5}}, "success.x"), ({"success": {"m": {"max": "a"}}}, "success.m.max"),
                       ({"success": {"m": {"min": 3, "max": 2}}}, "success.m")):
        with pytest.raises(ConfigError) as err:
            _uncertainty_spec(**bad)
        assert err.value.field == field
    with pytest.raises(ConfigError) as err:
        from continuum_sim.sensitivity.spec import parse_spec

        parse_spec({"method": "morris", "parameters": ["model.cable_friction.mu"], "success": {"m": {"max": 1}}})
    assert err.value.field == "success"


def test_uncertainty_analysis_counts_successes_with_the_exact_binomial_interval():
    from continuum_sim.sensitivity import uncertainty

    spec = _uncertainty_spec()
    values = np.array([[0.05, 4e10], [0.1, 5e10], [0.2, 6e10], [0.25, 7e10], [0.28, 3.5e10]])
    ok = {"status": "ok", "metrics": {"task.completed": 1.0, "cut_path_deviation_mm.mean": 2.0}}
    rows = [
        ok,
        ok,
        {"status": "ok", "metrics": {"task.completed": 1.0, "cut_path_deviation_mm.mean": 3.3}},
        {"status": "ok", "metrics": {"task.completed": 0.0, "task.failure": "cut_incomplete"}},
        None,
    ]
    a = uncertainty.analyze(spec, values, rows)
    assert (a["recorded"], a["successes"], a["completed"]) == (4, 2, 3)
    assert a["probability"] == 0.5
    assert a["failures"] == {"completed, but not cut_path_deviation_mm.mean <= 2.5": 1, "cut_incomplete": 1}
    # Clopper-Pearson against its closed form at the edges: k = 0 -> [0, 1 - (alpha/2)^(1/n)]
    low, high = uncertainty.clopper_pearson(0, 10)
    assert low == 0.0 and high == pytest.approx(1 - 0.025 ** (1 / 10), rel=1e-9)
    low, high = uncertainty.clopper_pearson(10, 10)
    assert high == 1.0 and low == pytest.approx(0.025 ** (1 / 10), rel=1e-9)
    # mu: both successes in the lower half of its range, none in the upper
    mu = a["success_by_half_range"]["model.cable_friction.mu"]
    assert mu["lower"] == {"n": 2, "success": 1.0} and mu["upper"] == {"n": 2, "success": 0.0}
    assert uncertainty.strength(spec, a)["model.cable_friction.mu"] == 1.0
    assert 0.0 <= a["base_position"]["model.cable_friction.mu"]["fraction_of_range"] <= 1.0


# --- confidence intervals and the sample sizes they need (SALib's conventions) -------------------------------------


def _analysis(**indices):
    return {"indices": {p: {"S1": v[0], "S1_conf": v[1], "ST": v[2], "ST_conf": v[3]} for p, v in indices.items()}}


def test_sobol_summary_table_shows_both_indices_with_their_intervals():
    from continuum_sim.sensitivity.report import summary_markdown

    summary = {"method": "sobol", "control_mode": "open", "evaluation": {"kind": "gravity_sag"}, "rows_recorded": 64, "rows": 64,
               "failed": 0, "completed_fraction": None, "cpu_s_total": 1.0, "metrics": ["sag_mm"],
               "parameters": [{"path": "a.b", "range": [0.0, 1.0], "log": False}], "strength": {"a.b": 1.0},
               "analysis": {"sag_mm": {"indices": {"a.b": {"S1": 0.61, "S1_conf": 0.12, "ST": 0.83, "ST_conf": 0.09}}}},
               "warnings": ["Sobol' N = 16 is too small"]}
    text = summary_markdown(summary)
    assert "| 0.83 ± 0.09 (0.61 ± 0.12) |" in text and "S_T ± 95 % (S1 ± 95 %)" in text
    assert "- **Warning:** Sobol' N = 16 is too small." in text


def test_sample_size_warnings_name_the_size_that_would_do():
    import tomllib

    from continuum_sim.sensitivity.design import sample_size_warnings

    two = 'parameters = ["model.cable_friction.mu", "plan.cut_speed"]\n'
    morris = parse_spec(tomllib.loads(two + "[morris]\ntrajectories = 4\n"))
    [warning] = sample_size_warnings(morris, {"m": {"trajectories_used": 4}})
    assert "r = 4" in warning and "r = 10 would do (30 runs for 2 parameters)" in warning
    enough = parse_spec(tomllib.loads(two + "[morris]\ntrajectories = 10\n"))
    assert sample_size_warnings(enough, {"m": {"trajectories_used": 10}}) == []
    dropped = sample_size_warnings(enough, {"m": {"trajectories_used": 7}})  # failed evaluations left 7 of 10
    assert len(dropped) == 1 and "only 7 of 10 trajectories" in dropped[0]

    small = parse_spec(tomllib.loads('method = "sobol"\n' + two + "[sobol]\nsamples = 16\n"))
    [warning] = sample_size_warnings(small, {"m": _analysis(**{"model.cable_friction.mu": (0.5, 0.1, 0.6, 0.1)})})
    assert "N = 16" in warning and "N = 64 would do (256 runs for 2 parameters)" in warning
    wide = parse_spec(tomllib.loads('method = "sobol"\n' + two + "[sobol]\nsamples = 64\n"))
    analyses = {"m": _analysis(**{"model.cable_friction.mu": (0.2, 0.3, 0.25, 0.5), "plan.cut_speed": (0.01, 0.2, 0.02, 0.3)})}
    [warning] = sample_size_warnings(wide, analyses)  # cut_speed's indices are below 0.05: noise around zero is no warning
    # S_T = 0.25 ± 0.5: half-widths shrink as 1/sqrt(N); half the index needs N * (2 * 0.5 / 0.25)^2 = 1024
    assert "ST of model.cable_friction.mu is 0.25 ± 0.5" in warning and "N = 1024 would bring it to about half (4096 runs)" in warning
    tight = {"m": _analysis(**{"model.cable_friction.mu": (0.5, 0.05, 0.6, 0.05)})}
    assert sample_size_warnings(wide, tight) == []
