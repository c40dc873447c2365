"""``continuum-sim evaluate``: a study's best design, evaluated again, gives the objective values the study recorded, exactly."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from continuum_sim.cli import main
from continuum_sim.optimize import load_spec, run_study
from continuum_sim.optimize.design import read_header

# The open-loop gravity hold (~0.2 s CPU per evaluation): 4 designs in generations of 2.
SPEC = """\
[variables]
"model.stiffness_scale" = {low = 0.5, high = 4.0, log = true}
"control.pretension" = {low = 15.0, high = 50.0}

[[objectives]]
metric = "sag_mm"

[[objectives]]
metric = "max_cable_tension_n"

[optimizer]
sampler = "nsga2"
trials = 4
batch = 2
seed = 0

[evaluation]
kind = "gravity_sag"
settle_s = 0.3
"""

ROBUST = SPEC.replace('metric = "sag_mm"', 'metric = "success_probability"').replace(
    'metric = "max_cable_tension_n"', 'metric = "sag_mm"\naggregate = "quantile"\nq = 0.75'
).replace("trials = 4", "trials = 2") + """
[constraints.metrics]
"sag_mm" = {max = 14.0}

[robustness]
samples = 2
parameters = ["model.rope_modulus"]
min_success = 0.5
"""


def _evaluate(capsys, *args: str) -> tuple[int, dict]:
    code = main(["evaluate", *args, "--json"])
    return code, json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("evaluate")
    (folder / "study.toml").write_text(SPEC)
    run_study(load_spec(folder / "study.toml"), folder / "out", workers=1, progress=False, spec_path=folder / "study.toml")
    return folder


def test_best_design_reproduces_its_recorded_objectives_exactly(study, capsys):
    out = study / "out"
    summary = json.loads((out / "summary.json").read_text())
    with (out / "trials.csv").open() as fh:
        rows = {int(r["trial"]): r for r in csv.DictReader(fh)}
    assert summary["best"]
    for best in summary["best"]:
        code, result = _evaluate(capsys, str(out / best["config"]))
        assert code == 0 and result["equal"] is True
        assert result["objectives"] == best["values"] == result["recorded"]  # floats compared exactly
        assert result["objectives"]["sag_mm"] == float(rows[best["trial"]]["sag_mm"])
    code = main(["evaluate", str(out / summary["best"][0]["config"])])  # the text form says so too
    assert code == 0 and "reproduced: every objective equals the recorded value exactly" in capsys.readouterr().out


def test_header_names_the_study_its_evaluation_and_provenance(study):
    out = study / "out"
    provenance = json.loads((out / "provenance.json").read_text())
    best = json.loads((out / "summary.json").read_text())["best"][0]
    text = (out / best["config"]).read_text()
    header = read_header(text)
    assert text.startswith("# continuum-sim design: trial ")
    assert header["study"] == str(out) and header["trial"] == best["trial"] and header["study_name"] == "optimize"
    assert header["spec_sha256"] == provenance["hashes"]["spec"] and header["commit"] == provenance["git"]["commit"]
    assert header["evaluation"] == {"kind": "gravity_sag", "q_deg": [60.0, 0.0, 30.0, 0.0, 0.0, 0.0], "settle_s": 0.3, "tool": "grinder"}
    assert header["values"] == best["values"] and header["samples"] == []
    from continuum_sim.scenario.config import ScenarioConfig

    config = ScenarioConfig.from_toml(out / best["config"])  # still a runnable scenario
    assert config.model.stiffness_scale == best["params"]["model.stiffness_scale"]


def test_spec_and_evaluation_options(study, capsys, tmp_path):
    out = study / "out"
    design = out / json.loads((out / "summary.json").read_text())["best"][0]["config"]
    code, by_spec = _evaluate(capsys, str(design), "--spec", str(study / "study.toml"))
    assert code == 0 and by_spec["equal"] is True
    code, same_kind = _evaluate(capsys, str(design), "--evaluation", "gravity_sag")  # the kind: the recorded settings of it
    assert code == 0 and same_kind["equal"] is True and same_kind["evaluation"]["settle_s"] == 0.3
    code, other = _evaluate(capsys, str(design), "--evaluation", '{"kind": "gravity_sag", "settle_s": 0.2}')
    assert code == 0 and other["equal"] is None and other["recorded"] is None  # another evaluation: nothing to compare
    edited = tmp_path / "edited.toml"  # a recorded value that the design does not give: exit 1, named
    text = design.read_text()
    recorded = read_header(text)["values"]["sag_mm"]
    edited.write_text(text.replace(repr(recorded), repr(recorded + 1e-9), 1))
    assert main(["evaluate", str(edited)]) == 1
    assert "DIFFERENT" in capsys.readouterr().out
    bare = tmp_path / "bare.toml"
    bare.write_text(design.read_text().split("\n\n", 1)[1])  # the scenario without its header
    assert main(["evaluate", str(bare)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--evaluation" in err[0] and "no study header" in err[0]
    code, metrics = _evaluate(capsys, str(bare), "--evaluation", '{"kind": "gravity_sag", "settle_s": 0.3}')
    assert code == 0 and metrics["objectives"] == {} and metrics["metrics"][0]["sag_mm"] == by_spec["objectives"]["sag_mm"]


def test_robust_best_design_reproduces_success_probability_and_quantile(tmp_path, capsys):
    (tmp_path / "robust.toml").write_text(ROBUST)
    result = run_study(load_spec(tmp_path / "robust.toml"), tmp_path / "out", workers=1, progress=False)
    assert result.n_trials == 2
    best = result.summary["best"]
    assert best
    for entry in best:
        header = read_header((tmp_path / "out" / entry["config"]).read_text())
        assert len(header["samples"]) == 2 and header["samples"][0][0][0] == "model.rope_modulus"
        code, out = _evaluate(capsys, str(tmp_path / "out" / entry["config"]))
        assert code == 0 and out["equal"] is True and out["samples"] == 2
        assert out["objectives"] == entry["values"] and out["success_probability"] == entry["success_probability"]
