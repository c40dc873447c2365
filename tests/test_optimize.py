"""Design optimisation: spec errors, per-section stiffness, seeded trials, kill and resume, robust aggregation."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from continuum_sim import ConfigError
from continuum_sim.optimize import load_spec, parse_spec, run_study
from continuum_sim.optimize.report import dominates, pareto_indices
from continuum_sim.optimize.study import aggregate
from continuum_sim.scenario.config import ScenarioConfig, merged

ROOT = Path(__file__).resolve().parents[1]

# A cheap evaluation (the open-loop gravity hold, ~0.1 s CPU): stiffness x300 makes the hinge springs diverge at the step
# (tests/test_sweep_resume.py), so the upper part of the range gives failed designs the study must record and survive.
SPEC = """\
[variables]
"model.stiffness_scale" = {low = 0.25, high = 400.0, log = true}
"control.pretension" = {low = 15.0, high = 50.0}

[[objectives]]
metric = "sag_mm"

[[objectives]]
metric = "max_cable_tension_n"
direction = "minimize"

[optimizer]
sampler = "nsga2"
trials = 12
batch = 4
seed = 3

[evaluation]
kind = "gravity_sag"
settle_s = 0.5
"""


def write(tmp_path: Path, text: str = SPEC, name: str = "study.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def trial_rows(folder: Path) -> list[dict[str, str]]:
    with (folder / "trials.csv").open() as fh:
        return list(csv.DictReader(fh))


def designs(folder: Path) -> list[tuple[str, str, str, str]]:
    return [(r["trial"], r["model.stiffness_scale"], r["control.pretension"], r["sag_mm"]) for r in trial_rows(folder)]


def audit(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "evaluations" / "log.jsonl").read_text().splitlines() if line.strip()]


@pytest.mark.parametrize(
    "edit, field",
    [
        (lambda s: s.replace('low = 0.25, high = 400.0', 'low = 400.0, high = 0.25'), "variables.model.stiffness_scale"),
        (lambda s: s.replace('"control.pretension"', '"control.no_such_field"'), "variables.control.no_such_field"),
        (lambda s: s.replace('metric = "sag_mm"', 'metric = "nonsense"'), "objectives[0].metric"),
        (lambda s: s.replace('direction = "minimize"', 'direction = "down"'), "objectives[1].direction"),
        (lambda s: s.replace('sampler = "nsga2"', 'sampler = "cmaes"'), "optimizer.sampler"),
        (lambda s: s.replace("trials = 12", "trials = 0"), "optimizer.trials"),
        (lambda s: s + '\n[robustness]\nsamples = 2\nparameters = ["model.cable_friction.mu"]\nmin_success = 0.5\n', "robustness.min_success"),
        (lambda s: s + '\n[robustness]\nsamples = 2\nparameters = ["arm.sections.0.length"]\n', "robustness.parameters[0]"),
    ],
)
def test_spec_errors_name_the_field_and_what_it_allows(tmp_path, edit, field):
    with pytest.raises(ConfigError) as info:
        load_spec(write(tmp_path, edit(SPEC)))
    assert info.value.field.endswith(field), info.value


def test_cli_spec_error_is_one_line_and_exit_2(tmp_path, capsys):
    from continuum_sim.cli import main

    path = write(tmp_path, SPEC.replace("batch = 4", "batch = 1"))  # NSGA-II needs a population of 2 or more
    assert main(["optimize", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "optimizer.batch" in err[0] and "2 <= batch <= 1024" in err[0], err
    assert not (tmp_path / "out").exists()


def test_section_stiffness_scale_multiplies_each_section():
    """The optimiser's per-section design variable is arm.sections.k.stiffness_scale: it scales that section's hinges."""
    from continuum_sim.configio import replace_path
    from continuum_sim.scenario.runner import build_scene_model

    def stiffness(model=None, scales=(1.0, 1.0, 1.0)):
        config = merged(ScenarioConfig.default(), {"model": model or {}})
        for k, value in enumerate(scales):
            config = replace_path(config, f"arm.sections.{k}.stiffness_scale", value)
        return build_scene_model(config)[1].jnt_stiffness.copy()

    base, uniform, scaled = stiffness(), stiffness({"stiffness_scale": 2.0}), stiffness(scales=(2.0, 2.0, 2.0))
    np.testing.assert_allclose(uniform, scaled, rtol=1e-14)  # (2, 2, 2) is stiffness_scale = 2
    middle = stiffness(scales=(1.0, 3.0, 1.0))
    changed = np.flatnonzero(~np.isclose(middle, base))
    assert changed.size > 0 and np.allclose(middle[changed], 3.0 * base[changed])
    assert 0 < changed.size < np.count_nonzero(base)  # the middle section's hinges only, not the others


def test_same_seed_same_trials_any_worker_count_and_failures_recorded(tmp_path):
    spec = load_spec(write(tmp_path))
    one = run_study(spec, tmp_path / "w1", workers=1, progress=False)
    two = run_study(spec, tmp_path / "w2", workers=2, progress=False)
    assert designs(tmp_path / "w1") == designs(tmp_path / "w2")  # parameters and metrics, trial by trial
    distinct = {d[1:3] for d in designs(tmp_path / "w1")}  # NSGA-II may propose a design again: its evaluation is reused
    assert one.n_trials == two.n_trials == 12 and one.n_evaluated == len(distinct) and one.n_evaluated + one.n_reused == 12
    rows = trial_rows(tmp_path / "w1")
    failed = [r for r in rows if r["state"] == "FAIL"]
    assert failed and all(r["failure"].startswith("diverged") for r in failed)  # named, and the study went on
    assert all(float(r["model.stiffness_scale"]) > 16 for r in failed)
    other = run_study(load_spec(write(tmp_path, SPEC.replace("seed = 3", "seed = 4"), "other.toml")), tmp_path / "s4", workers=2, progress=False)
    assert other.n_trials == 12 and designs(tmp_path / "s4") != designs(tmp_path / "w1")
    summary = json.loads((tmp_path / "w1" / "summary.json").read_text())
    front = [[b["values"]["sag_mm"], b["values"]["max_cable_tension_n"]] for b in summary["best"]]
    done = [[float(r["sag_mm"]), float(r["max_cable_tension_n"])] for r in rows if r["state"] == "COMPLETE"]
    assert front and not any(dominates(p, f, ["minimize", "minimize"]) for p in done for f in front)
    for best in summary["best"]:  # runnable scenario files with the design in them
        config = ScenarioConfig.from_toml(tmp_path / "w1" / best["config"])
        assert config.model.stiffness_scale == pytest.approx(best["params"]["model.stiffness_scale"])
    assert (tmp_path / "w1" / "plots" / "pareto.png").stat().st_size > 10_000


def test_killed_study_resumes_to_the_same_trials_without_evaluating_twice(tmp_path):
    text = SPEC.replace("trials = 12", "trials = 16").replace("settle_s = 0.5", "settle_s = 2.0")
    path = write(tmp_path, text)
    out = tmp_path / "killed"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "continuum_sim", "optimize", str(path), "--out", str(out), "--workers", "2", "--quiet"]
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 180
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            if (out / "evaluations" / "log.jsonl").exists() and len(audit(out)) >= 6:
                break
            time.sleep(0.02)
        assert proc.poll() is None, "the study finished before it could be killed"
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    before = len(audit(out))
    assert 6 <= before < 16

    resumed = run_study(load_spec(path), out, workers=2, progress=False)
    lines = audit(out)
    ids = [line["variant_id"] for line in lines]
    distinct = {d[1:3] for d in designs(out)}
    assert len(ids) == len(set(ids)) == len(distinct)  # every distinct design evaluated exactly once over both runs
    assert resumed.n_evaluated == len(distinct) - before and resumed.n_trials == 16
    rows = trial_rows(out)
    assert [r["trial"] for r in rows] == [str(i) for i in range(16)] and all(r["state"] in ("COMPLETE", "FAIL") for r in rows)
    reference = run_study(load_spec(path), tmp_path / "reference", workers=2, progress=False)  # uninterrupted, same seed
    assert reference.n_trials == 16 and designs(out) == designs(tmp_path / "reference")


def test_robust_aggregation_success_probability_quantile_and_failures():
    text = SPEC.replace('metric = "sag_mm"', 'metric = "success_probability"').replace(
        'metric = "max_cable_tension_n"\ndirection = "minimize"', 'metric = "sag_mm"\naggregate = "quantile"\nq = 0.5'
    ) + '\n[constraints.metrics]\n"sag_mm" = {max = 10.0}\n\n[robustness]\nsamples = 4\nparameters = ["model.cable_friction.mu"]\nmin_success = 0.5\n'
    spec = parse_spec(__import__("tomllib").loads(text))
    assert spec.directions == ["maximize", "minimize"]
    records = [
        {"status": "ok", "metrics": {"sag_mm": 5.0}, "error": None},
        {"status": "ok", "metrics": {"sag_mm": 12.0}, "error": None},
        {"status": "ok", "metrics": {"sag_mm": 7.0}, "error": None},
        {"status": "failed", "metrics": {}, "error": "diverged: qacc"},
    ]
    out = aggregate(spec, records)
    assert out["success_probability"] == 0.5  # 5 and 7 hold; 12 breaks the bound; the failed sample is no success
    assert out["values"] == [0.5, 7.0]  # median over the evaluations that ran
    assert out["constraints"] == [0.0] and out["failures"] == ["diverged: qacc"]
    assert aggregate(spec, records[1:2] + records[3:])["constraints"] == [0.5]  # p = 0 < 0.5: infeasible by 0.5
    assert aggregate(spec, records[3:])["values"] is None  # nothing ran: the design fails with its named reason


def test_pareto_indices_against_brute_force():
    rng = np.random.default_rng(0)
    points = rng.integers(0, 6, size=(40, 2)).astype(float).tolist()
    directions = ["minimize", "maximize"]
    keep = set(pareto_indices(points, directions))
    for i, (a0, a1) in enumerate(points):
        dominated = any(b0 <= a0 and b1 >= a1 and (b0 < a0 or b1 > a1) for b0, b1 in points)
        assert (i in keep) == (not dominated)


def test_hypervolume_2d_of_a_staircase_and_with_a_maximised_objective():
    from continuum_sim.optimize.compare import hypervolume_2d

    assert hypervolume_2d([[1, 3], [2, 2], [3, 1], [3.5, 3.5]], [4, 4], ["minimize", "minimize"]) == pytest.approx(6.0)
    # maximising the second objective: mirror it
    assert hypervolume_2d([[1, -3], [2, -2], [3, -1]], [4, -4], ["minimize", "maximize"]) == pytest.approx(6.0)


def test_grid_sampler_visits_every_grid_point_once(tmp_path):
    text = SPEC.replace('high = 400.0, log = true}', 'high = 4.0, log = true, grid = 3}').replace("high = 50.0}", "high = 50.0, grid = 2}")
    text = text.replace('sampler = "nsga2"', 'sampler = "grid"').replace("trials = 12", "trials = 6").replace("batch = 4", "batch = 3")
    spec = load_spec(write(tmp_path, text))
    result = run_study(spec, tmp_path / "grid", workers=2, progress=False)
    points = {(float(r["model.stiffness_scale"]), float(r["control.pretension"])) for r in trial_rows(tmp_path / "grid")}
    assert points == {(s, p) for s in (0.25, 1.0, 4.0) for p in (15.0, 50.0)} and result.n_evaluated == 6


def test_robust_study_end_to_end_success_probability_from_its_samples(tmp_path):
    text = SPEC.replace('metric = "sag_mm"', 'metric = "success_probability"').replace("trials = 12", "trials = 4")
    text += '\n[constraints.metrics]\n"sag_mm" = {max = 16.0}\n\n[robustness]\nsamples = 3\nparameters = ["model.rope_modulus"]\nmin_success = 0.5\n'
    text = text.replace("high = 400.0", "high = 8.0")
    result = run_study(load_spec(write(tmp_path, text)), tmp_path / "robust", workers=2, progress=False)
    assert result.n_trials == 4 and result.n_evaluated + result.n_reused == 12
    records = {p.stem: json.loads(p.read_text()) for p in (tmp_path / "robust" / "evaluations" / "records").glob("*.json")}
    moduli = {r["params"]["model.rope_modulus"] for r in records.values()}
    assert len(moduli) == 3  # the same three plants for every design (common random numbers)
    from continuum_sim.optimize.study import open_study

    for trial in open_study(load_spec(tmp_path / "study.toml"), tmp_path / "robust").get_trials():
        samples = [records[i] for i in trial.user_attrs["variant_ids"]]
        held = [r["status"] == "ok" and r["metrics"]["sag_mm"] <= 16.0 for r in samples]
        assert trial.user_attrs["success_probability"] == pytest.approx(sum(held) / 3)
        assert trial.values[0] == pytest.approx(sum(held) / 3)
        assert trial.user_attrs["constraints"] == pytest.approx([0.5 - sum(held) / 3])


def test_cli_flags_override_the_spec_optuna_storage_names_and_best_trials(tmp_path, capsys):
    """--trials/--seed run a spec without editing it; --storage sqlite and --study-name put the study where Optuna's own
    API finds it, with the objectives' names; the report's front is Optuna's best_trials; --trials extends the study."""
    import optuna

    from continuum_sim.cli import main

    text = SPEC.replace("high = 400.0", "high = 8.0")  # no diverging designs: a short study
    path = write(tmp_path, text)
    url = f"sqlite:///{tmp_path / 'studies.db'}"
    out = tmp_path / "flags"
    args = ["optimize", str(path), "--out", str(out), "--trials", "6", "--seed", "1", "--storage", url, "--study-name", "s1",
            "--workers", "1", "--quiet"]
    assert main(args) == 0
    assert path.read_text() == text  # the spec is as written
    rows = trial_rows(out)
    assert [r["trial"] for r in rows] == [str(i) for i in range(6)]
    study = optuna.load_study(storage=url, study_name="s1")
    assert study.metric_names == ["sag_mm", "max_cable_tension_n"] and len(study.trials) == 6
    frame = study.trials_dataframe()
    assert {"values_sag_mm", "values_max_cable_tension_n"} <= set(frame.columns) and "values_0" not in frame.columns
    summary = json.loads((out / "summary.json").read_text())
    assert summary["optuna"]["study_name"] == "s1" and summary["optuna"]["storage"] == url and summary["seed"] == 1
    assert summary["budget"] == 6 and not (out / "study.journal").exists()
    # the same seed from the spec in the folder's journal gives the same trials: the storage changes nothing
    same = run_study(load_spec(write(tmp_path, text.replace("seed = 3", "seed = 1").replace("trials = 12", "trials = 6"), "s1.toml")),
                     tmp_path / "journal", workers=1, progress=False)
    assert same.n_trials == 6 and designs(tmp_path / "journal") == designs(out)
    # the report's front is Optuna's best_trials, which the project's own filter agrees with
    best = sorted(t.number for t in study.best_trials)
    assert [int(r["trial"]) for r in trial_rows(out) if r["trial"] in {str(b) for b in best}] == [b["trial"] for b in summary["best"]]
    done = [t for t in study.trials if t.state.name == "COMPLETE"]
    assert sorted(done[i].number for i in pareto_indices([list(t.values) for t in done], ["minimize", "minimize"])) == best
    with (out / "pareto.csv").open() as fh:
        assert sorted(int(r["trial"]) for r in csv.DictReader(fh)) == best
    if __import__("importlib").util.find_spec("pyarrow") is not None:
        import pyarrow.parquet as pq

        table = pq.read_table(out / "trials.parquet").to_pydict()
        assert table["trial"] == [float(r["trial"]) for r in rows] and table["sag_mm"] == [float(r["sag_mm"]) for r in rows]
        assert sorted(pq.read_table(out / "pareto.parquet").to_pydict()["trial"]) == [float(b) for b in best]
    # --trials 8 on the same folder and storage extends the study: the first 6 trials untouched, 2 designs more
    capsys.readouterr()
    assert main([*args[:5], "8", *args[6:]]) == 0
    assert [r[:3] for r in designs(out)][:6] == [r[:3] for r in designs(tmp_path / "journal")]
    assert len(trial_rows(out)) == 8 and len(optuna.load_study(storage=url, study_name="s1").trials) == 8
    # another spec under the same study name is refused: one line naming --study-name, exit 2
    other = write(tmp_path, text.replace('metric = "sag_mm"', 'metric = "sag_z_mm"'), "other.toml")
    capsys.readouterr()
    assert main(["optimize", str(other), "--out", str(tmp_path / "other"), "--storage", url, "--study-name", "s1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--study-name" in err[0] and "another spec" in err[0], err


def test_trials_and_seed_overrides_are_checked_like_the_spec(tmp_path):
    from continuum_sim.optimize.spec import with_optimizer

    spec = load_spec(write(tmp_path))
    assert with_optimizer(spec, trials=5, seed=9).optimizer == type(spec.optimizer)("nsga2", 5, 4, 9)
    assert with_optimizer(spec).optimizer == spec.optimizer
    for kwargs, field in (({"trials": 0}, "--trials"), ({"seed": -1}, "--seed"), ({"trials": 10**6}, "--trials")):
        with pytest.raises(ConfigError) as info:
            with_optimizer(spec, **kwargs)
        assert info.value.field == field


def test_parquet_is_skipped_without_pyarrow(tmp_path, monkeypatch):
    """Without pyarrow the tables are CSV only (summary.json says so in ``notes``); nothing half-written is left."""
    from continuum_sim.optimize.report import PARQUET_MISSING, write_parquet
    from continuum_sim.sensitivity.report import write_parquet as write_samples_parquet

    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow raises ImportError
    assert write_parquet([{"trial": 0, "sag_mm": 1.5}], ["trial", "sag_mm"], tmp_path / "trials.parquet") is False
    assert write_samples_parquet(["row", "sag_mm"], [[0, 1.5]], tmp_path / "samples.parquet") is False
    assert not list(tmp_path.iterdir()) and "pyarrow" in PARQUET_MISSING
