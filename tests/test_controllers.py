"""Bring-your-own controller: from the configuration or --controller, checked before the run."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from continuum_sim.configio import ConfigError
from continuum_sim.controllers import Controller, ControllerError, load_controller
from continuum_sim.scenario.config import ScenarioConfig, merged
from continuum_sim.scenario.runner import run_scenario

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = "examples.hold_controller:SlowGripOpenLoop"


def test_the_example_controller_runs_the_task_from_the_configuration(monkeypatch):
    monkeypatch.chdir(ROOT)
    config = merged(ScenarioConfig.default(), {"control": {"controller": EXAMPLE}})
    assert isinstance(load_controller(EXAMPLE), Controller)
    metrics = run_scenario(config, None, stages=("initial", "clamping"))
    assert metrics["control"] == EXAMPLE
    # Open-loop cables: the gripper arm strays further than under the built-in closed loop, but the arms stay apart.
    assert 0.0 < metrics["tip_error_mm"]["right"]["clamping"]["mean"] < 100.0
    assert not metrics["arms_touched"]


@pytest.mark.parametrize(
    "spec, fragment",
    [
        ("no_such_module_xyz:Thing", "cannot import 'no_such_module_xyz'"),
        ("examples.hold_controller:Missing", "has no 'Missing'"),
        ("continuum_sim.layout:TaskLayout", "does not satisfy the Controller protocol"),
    ],
)
def test_a_broken_controller_is_refused(monkeypatch, spec, fragment):
    monkeypatch.chdir(ROOT)
    with pytest.raises(ControllerError, match=fragment):
        load_controller(spec)


def test_a_malformed_spec_is_a_config_error():
    with pytest.raises(ConfigError, match="control.controller: must be empty or 'package.module:ClassName'"):
        merged(ScenarioConfig.default(), {"control": {"controller": "not a spec"}})


def test_cli_refuses_a_broken_controller_in_one_line(tmp_path):
    out = tmp_path / "run"
    result = subprocess.run(
        [sys.executable, "-m", "continuum_sim", "run", "--controller", "continuum_sim.layout:TaskLayout",
         "--out", str(out), "--quiet"],
        capture_output=True, text=True, cwd=ROOT,
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "control.controller" in lines[0] and "Controller protocol" in lines[0]
    assert not out.exists()
