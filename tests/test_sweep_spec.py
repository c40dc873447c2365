"""Sweep specs: grid expansion, stable ids, and one-line errors before any work."""

import subprocess
import sys
from pathlib import Path

import pytest

from continuum_sim import ConfigError
from continuum_sim.scenario.metrics import WALL_CLOCK_METRICS
from continuum_sim.sweep import GravitySag, Stage, load_spec, parse_spec
from continuum_sim.sweep import worker as sweep_worker

ROOT = Path(__file__).resolve().parents[1]


def spec_of(grid, evaluation=None, **extra):
    return parse_spec({"grid": grid, "evaluation": evaluation or {"kind": "gravity_sag"}, **extra})


def test_grid_is_the_cartesian_product_in_order_with_stable_distinct_ids():
    spec = spec_of(
        {
            "model.stiffness_scale": {"start": 0.5, "stop": 8, "num": 5, "scale": "log"},
            "arm.sections.1.hinge_width": [0.004, 0.005],
        }
    )
    assert spec.axes[0].values == (0.5, 1.0, 2.0, 4.0, 8.0)  # clean log values
    assert spec.axes[0].log and not spec.axes[1].log
    variants = spec.variants()
    assert [v.index for v in variants] == list(range(10))
    assert variants[1].param_dict == {"model.stiffness_scale": 0.5, "arm.sections.1.hinge_width": 0.005}
    assert len({v.variant_id for v in variants}) == 10
    again = spec_of({"model.stiffness_scale": [0.5, 1, 2, 4, 8], "arm.sections.1.hinge_width": [0.004, 0.005]})
    assert [v.variant_id for v in again.variants()] == [v.variant_id for v in variants]
    # the evaluation is part of the id: another settle time is another variant
    other = spec_of({"model.stiffness_scale": [0.5]}, {"kind": "gravity_sag", "settle_s": 1.0})
    assert other.variants()[0].variant_id != variants[0].variant_id
    config = spec.config_for(variants[3])
    assert config.model.stiffness_scale == 1.0 and config.arm.sections[1].hinge_width == 0.005
    # integer fields stay integers
    ints = spec_of({"model.segments_per_section": [3, 4.0]})
    assert ints.axes[0].values == (3, 4) and all(isinstance(v, int) for v in ints.axes[0].values)


def test_defaults_and_evaluation_parameters():
    spec = spec_of({"model.stiffness_scale": [1.0]}, {"kind": "gravity_sag", "q_deg": [45, 0, 45, 0, 0, 0]})
    assert isinstance(spec.evaluation, GravitySag)
    assert spec.evaluation.q_deg == (45.0, 0.0, 45.0, 0.0, 0.0, 0.0)
    assert spec.metrics == spec.evaluation.known_metrics()
    stage = spec_of({"model.stiffness_scale": [1.0]}, {"kind": "stage", "stage": "clamping"}, metrics=["tip_error_mm.right.clamping.mean"])
    assert isinstance(stage.evaluation, Stage) and stage.metrics == ("tip_error_mm.right.clamping.mean",)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"grid": {"model.stifness_scale": [1.0]}}, r"grid\.model\.stifness_scale: unknown parameter path: model has no 'stifness_scale' \(it has fields joint, segments_per_section, stiffness_scale"),
        ({"grid": {"arm.sections.7.hinge_width": [0.004]}}, r"arm\.sections has no '7' \(it has indices 0 to 2\)"),
        ({"grid": {"wobble": [1.0]}}, r"the scenario configuration has no 'wobble' \(it has fields arm, layout, model"),
        ({"grid": {}}, r"grid: empty"),
        ({"grid": {"model.stiffness_scale": []}}, r"grid\.model\.stiffness_scale: empty list"),
        ({"grid": {"model.stiffness_scale": [1.0, "stiff"]}}, r"stiffness_scale\[1\]: must be a number \(got str 'stiff'\)"),
        ({"grid": {"model.stiffness_scale": [True]}}, r"must be a number \(got bool"),
        ({"grid": {"model.joint": ["ball"]}}, r"grid\.model\.joint: not a numeric field"),
        ({"grid": {"arm.sections": [1.0]}}, r"grid\.arm\.sections: not a numeric field \(it is a list\)"),
        ({"grid": {"model.segments_per_section": [2.5]}}, r"is an integer field"),
        ({"grid": {"model.stiffness_scale": [1.0, 1.0]}}, r"appears twice"),
        ({"grid": {"model.stiffness_scale": {"start": 0, "stop": 1, "num": 3, "scale": "log"}}}, r"log range needs start > 0"),
        ({"grid": {"model.stiffness_scale": {"start": 1, "stop": 2}}}, r"missing num"),
        ({"grid": {"model.stiffness_scale": [1.0, -2.0]}}, r"model\.stiffness_scale: must satisfy 0 < stiffness_scale .*variant 1"),
        ({"grid": {"model.stiffness_scale": [1.0]}, "evaluation": {"kind": "wobble"}}, r"evaluation\.kind: must be one of gravity_sag"),
        ({"grid": {"model.stiffness_scale": [1.0]}, "evaluation": {"kind": "gravity_sag", "settle": 1}}, r"evaluation\.settle: unknown key"),
        ({"grid": {"model.stiffness_scale": [1.0]}, "metrics": ["sag"]}, r"metrics\[0\]: unknown metric 'sag'"),
        ({"grid": {"model.stiffness_scale": [1.0]}, "metrics": []}, r"metrics: must be a non-empty list"),
        ({"grid": {"model.stiffness_scale": [1.0]}, "evaluation": {"kind": "gravity_sag", "q_deg": [95, 0, 0, 0, 0, 0]}}, r"θ0 must satisfy 0 <= θ0 <= max_bend_deg = 90"),
        ({"grid": {"arm.sections.0.max_bend_deg": [90, 40]}, "evaluation": {"kind": "gravity_sag"}}, r"θ0 must satisfy .* 40 .*variant 1"),
        ({"grid": {"model.stiffness_scale": [1.0]}, "evaluation": {"kind": "tip_deflection", "q_deg": [30, 0, 0, 0, 0, 0]}}, r"cables = 'free'"),
        ({"grid": {"model.stiffness_scale": [1.0]}, "evaluation": None}, r"evaluation: missing"),
        ({"grid": {"model.stiffness_scale": [1.0]}, "evaluation": {"kind": "gravity_sag"}, "gird": 1}, r"gird: unknown key"),
    ],
)
def test_bad_specs_are_rejected_with_a_field_naming_message(data, message):
    data = {"evaluation": {"kind": "gravity_sag"}, **data}
    if data["evaluation"] is None:
        del data["evaluation"]
    with pytest.raises(ConfigError, match=message):
        parse_spec(data)


def test_stage_evaluation_runs_the_scenario_and_flattens_its_metrics():
    """A real ``run_scenario`` of the first stage, for one stiffness variant."""
    spec = spec_of({"model.stiffness_scale": [2.0]}, {"kind": "stage", "stage": "initial"})
    metrics = sweep_worker.evaluate(spec.config_for(spec.variants()[0]), spec.evaluation)
    assert metrics["sample_detached"] == 0.0
    assert metrics["tip_error_mm.left.initial.mean"] < 1e-6  # the straight arm holds its pose
    assert not [key for key in metrics if key.split(".")[0] in WALL_CLOCK_METRICS]
    assert all(isinstance(v, float) or v is None or isinstance(v, str) for v in metrics.values())


def test_diverging_scenario_variant_is_recorded_as_failed():
    from continuum_sim.configio import to_dict
    from continuum_sim.scenario.config import ScenarioConfig, merged

    config = merged(ScenarioConfig(), {"model": {"timestep": 0.01, "cable_implicit_spring": False, "stable_step": False, "cable_max_force": 1.0e5}})
    result = sweep_worker.evaluate_payload({"config": to_dict(config), "evaluation": {"kind": "stage", "stage": "clamping"}})
    assert result["status"] == "failed" and "diverged" in result["error"]


def test_load_spec_resolves_base_relative_to_the_spec(tmp_path):
    (tmp_path / "scn.toml").write_text("[model]\nstiffness_scale = 3.0\n")
    (tmp_path / "s.toml").write_text('base = "scn.toml"\n[grid]\n"control.pretension" = [5, 10]\n[evaluation]\nkind = "gravity_sag"\n')
    spec = load_spec(tmp_path / "s.toml")
    assert spec.base.model.stiffness_scale == 3.0 and spec.axes[0].values == (5.0, 10.0)
    (tmp_path / "t.toml").write_text('base = "missing.toml"\n[grid]\n"control.pretension" = [5]\n[evaluation]\nkind = "gravity_sag"\n')
    with pytest.raises(ConfigError, match=r"t\.toml: base: scenario file .*missing\.toml' not found"):
        load_spec(tmp_path / "t.toml")


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ('[grid]\n"model.nope" = [1.0]\n[evaluation]\nkind = "gravity_sag"\n', "grid.model.nope: unknown parameter path: model has no 'nope'"),
        ('[grid]\n[evaluation]\nkind = "gravity_sag"\n', "grid: empty"),
        ('[grid]\n"model.stiffness_scale" = ["a", "b"]\n[evaluation]\nkind = "gravity_sag"\n', "must be a number"),
    ],
)
def test_cli_bad_spec_is_one_line_exit_2_and_no_work(tmp_path, body, message):
    spec = tmp_path / "bad.toml"
    spec.write_text(body)
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "continuum_sim", "sweep", str(spec), "--out", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("continuum-sim sweep: error: ") and message in lines[0], proc.stderr
    assert not out.exists()
