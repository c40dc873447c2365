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
        ({"model": {"jacobian": "diagonal"}}, "model.jacobian"),
        ({"model": {"cable_path": "wireless"}}, "model.cable_path"),
        ({"model": {"impratio": 0.5}}, "model.impratio"),
        ({"plan": {"return_offset": -0.001}}, "plan.return_offset"),
        ({"control": {"max_extra_tension": -1.0}}, "control.max_extra_tension"),
        ({"scene": {"tools": {"gripper_pad_thickness": 0.0}}}, "scene.tools.gripper_pad_thickness"),
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


def test_scene_options_reach_the_model_and_the_runner(tmp_path):
    """Tool settings live in the scenario config (saved with every run) and reach the model."""
    from continuum_sim.scenario.runner import build_scene_model

    path = tmp_path / "stronger_grip.toml"
    path.write_text("[scene.tools]\ngripper_max_force = 3.5\npad_friction = 0.8\n")
    config = ScenarioConfig.from_toml(path)
    assert config.scene.tools.gripper_max_force == 3.5
    _, model = build_scene_model(config)
    cable = model.actuator("right/gripper/cable")
    assert cable.forcerange[0] == -3.5
    assert cable.ctrlrange[0] == config.scene.tools.gripper_cable_closed  # the runner's closing command is in range
    assert model.geom("right/gripper/pad_a").friction[0] == 0.8
    saved = tmp_path / "saved.toml"
    config.save_toml(saved)
    assert ScenarioConfig.from_toml(saved) == config


def test_bad_scene_option_names_the_dotted_field(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[scene.tools]\ngripper_max_force = -1.0\n")
    with pytest.raises(ConfigError, match="gripper_max_force"):
        ScenarioConfig.from_toml(path)
