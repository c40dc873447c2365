"""The parameter registry: complete, consistent with the shipped config, its CLI and its generated doc."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from continuum_sim.configio import ConfigError, get_path
from continuum_sim.params import REGISTRY, STATUSES, apply, parameter, records, values
from continuum_sim.cli.params import document, render_markdown
from continuum_sim.scenario.config import ScenarioConfig

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def default() -> ScenarioConfig:
    return ScenarioConfig.default()


def test_registry_is_complete_and_every_path_resolves(default):
    assert len(REGISTRY) >= 25
    paths = [p.path for p in REGISTRY]
    assert len(set(paths)) == len(paths), "a path is listed twice"
    for p in REGISTRY:
        assert p.status in STATUSES, p.path
        assert p.unit and p.source and p.name, p.path
        value = get_path(default, p.path)  # raises for a path the config does not have
        assert isinstance(value, (int, float)) and not isinstance(value, bool), p.path
        if p.status == "assumed":
            assert p.range is not None, f"{p.path} is assumed but has no plausible range"
        if p.range is not None:
            low, high = p.range
            assert low < high, p.path
            assert p.in_range(p.value(default)), f"{p.path}: default {p.value(default)} outside {p.range}"
            if p.log:
                assert low > 0.0 and high / low >= 4.0, f"{p.path}: a log range must be positive and wide"
    # the figures the issue names are in the registry, at their defaults
    assert parameter("model.cable_friction.mu").value(default) == 0.15
    assert parameter("scene.foam.specific_energy").range == (1.3e5, 2.0e6)


def test_values_come_from_the_config_not_the_registry(default):
    changed = apply(default, {"model.cable_friction.mu": 0.05, "arm.sections.0.leaf_free_length": 0.004})
    now = values(changed)
    assert now["model.cable_friction.mu"] == 0.05 == changed.model.cable_friction.mu
    assert now["arm.sections.0.leaf_free_length"] == 0.004
    # the free length 0 of the shipped file means the whole gap between the disks
    section = default.arm.sections[1]
    assert values(default)["arm.sections.1.leaf_free_length"] == pytest.approx(section.pitch - default.arm.disk_thickness)
    doc = records(changed, default)
    assert doc["overrides"] == {"model.cable_friction.mu": 0.05, "arm.sections.0.leaf_free_length": 0.004}
    flagged = {r["path"] for r in doc["parameters"] if r["overridden"]}
    assert flagged == set(doc["overrides"])


@pytest.mark.parametrize(
    ("setting", "expected"),
    [
        ("model.cable_friction.mu=0.5", "model.cable_friction.mu: must satisfy 0 <= value <= 0.3"),
        ("model.cable_frction.mu=0.1", "did you mean model.cable_friction.mu"),
        ("scene.foam.specific_energy=lots", "must be a number in [130000, 2e+06] J/m³"),
        ("model.cable_friction.mu=nan", "must be a finite number"),
        ("model.cable_friction.mu", "--set: must be PATH=VALUE"),
    ],
)
def test_bad_overrides_are_one_line_errors(setting, expected):
    with pytest.raises(ConfigError) as info:
        document(None, [setting])
    assert expected in str(info.value)


def test_params_cli_exit_codes(tmp_path):
    env_cmd = [sys.executable, "-m", "continuum_sim", "params"]
    bad = subprocess.run([*env_cmd, "--set", "model.rope_modulus=1e12"], capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2
    lines = bad.stderr.strip().splitlines()
    assert len(lines) == 1 and "model.rope_modulus" in lines[0] and "3e+10 <= value <= 7.5e+10" in lines[0]
    good = subprocess.run([*env_cmd, "--format", "json", "--set", "control.pretension=20"], capture_output=True, text=True, cwd=ROOT)
    assert good.returncode == 0, good.stderr
    doc = json.loads(good.stdout)
    assert doc["overrides"] == {"control.pretension": 20.0}
    assert next(r for r in doc["parameters"] if r["path"] == "control.pretension")["value"] == 20.0


def test_docs_parameters_md_is_in_step():
    text = (ROOT / "docs" / "parameters.md").read_text()
    assert text == render_markdown(document()), "docs/parameters.md is stale: continuum-sim params --format markdown > docs/parameters.md"


def test_run_folder_records_parameters(tmp_path, default):
    from continuum_sim.scenario.runner import write_parameters

    config = apply(default, {"scene.tools.gripper_preload": 0.3})
    write_parameters(tmp_path, config)
    doc = json.loads((tmp_path / "parameters.json").read_text())
    assert doc["overrides"] == {"scene.tools.gripper_preload": 0.3}
    row = next(r for r in doc["parameters"] if r["path"] == "scene.tools.gripper_preload")
    assert row["value"] == 0.3 and row["overridden"] is True and row["range"] == [0.25, 1.0]
    assert {"path", "value", "unit", "status", "source", "range", "overridden"} <= set(row)
