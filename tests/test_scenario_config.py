"""Scenario configuration: shipped TOML equals the code defaults; overrides validate."""

import pytest

from continuum_sim import ConfigError
from continuum_sim.scenario.config import ScenarioConfig, merged


def test_shipped_toml_matches_code_defaults():
    assert ScenarioConfig.default() == ScenarioConfig()


def test_user_file_overrides_a_subset(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[control]\nmode = "open"\n[model]\nstiffness_scale = 2.0\n')
    config = ScenarioConfig.from_toml(path)
    assert config.control.mode == "open" and config.model.stiffness_scale == 2.0
    assert config.arm == ScenarioConfig().arm
    saved = tmp_path / "saved.toml"
    config.save_toml(saved)
    assert ScenarioConfig.from_toml(saved) == config


@pytest.mark.parametrize(
    "overrides, field",
    [
        ({"control": {"mode": "half"}}, "control.mode"),
        ({"model": {"timestep": -1.0}}, "model.timestep"),
        ({"simulation": {"video_width": 3}}, "simulation.video_width"),
        ({"layout": {"plate": {"size": [0.2, 0.15]}}}, "layout.plate.size"),
        ({"nonsense": 1}, "nonsense"),
    ],
)
def test_bad_overrides_name_the_field(overrides, field):
    with pytest.raises(ConfigError) as info:
        merged(ScenarioConfig(), overrides)
    assert info.value.field == field


def test_shipped_toml_is_regenerated_text():
    from importlib import resources

    from continuum_sim.scenario.config import default_scenario_toml

    shipped = resources.files("continuum_sim").joinpath("data/scenario.toml").read_text()
    assert shipped == default_scenario_toml(), "run `continuum-sim build-model` to regenerate"
