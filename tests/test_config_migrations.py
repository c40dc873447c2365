"""Removed and renamed config keys: every unknown-key error names what replaces them (configio.MIGRATIONS)."""

import tomllib

import pytest

from continuum_sim import ConfigError
from continuum_sim.cli import main
from continuum_sim.configio import MIGRATIONS, get_path, migration_note, replace_path
from continuum_sim.scenario.config import ScenarioConfig, merged

REPLACEMENT = "arm.sections.<k>.stiffness_scale"


def test_every_old_path_is_gone_and_every_replacement_exists():
    defaults = ScenarioConfig.default()
    for old, (new, why) in MIGRATIONS.items():
        with pytest.raises(ConfigError):
            get_path(defaults, old)
        assert why and "\n" not in why
        if new is not None:
            get_path(defaults, new.replace("<k>", "0"))  # raises if the replacement is not a field


def test_note_fills_in_a_section_index():
    assert "use arm.sections.2.stiffness_scale instead" in migration_note("model.section_stiffness_scale.2")
    assert f"use {REPLACEMENT} instead" in migration_note("model.section_stiffness_scale")
    assert "nothing replaces it" in migration_note("scene.foam.native")
    assert migration_note("model.stiffness_scale") is None
    assert migration_note("model.section_stiffness_scale_x") is None


def test_scenario_toml_names_the_replacement(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[model]\nsection_stiffness_scale = [1.0, 1.2, 0.9]\n")
    with pytest.raises(ConfigError) as info:
        ScenarioConfig.from_toml(bad)
    text = str(info.value)
    assert "model.section_stiffness_scale" in text and REPLACEMENT in text and "allowed keys" not in text


def test_other_removed_keys_in_a_scenario():
    with pytest.raises(ConfigError, match="scene.kerf_cell_length: removed; use scene.foam.voxel_size"):
        merged(ScenarioConfig(), {"scene": {"kerf_cell_length": 0.005}})
    with pytest.raises(ConfigError, match="scene.tools.cutter_shell: removed, nothing replaces it"):
        merged(ScenarioConfig(), {"scene": {"tools": {"cutter_shell": 0.001}}})


def test_an_unknown_key_that_never_existed_still_lists_the_allowed_keys():
    with pytest.raises(ConfigError, match="allowed keys are"):
        merged(ScenarioConfig(), {"model": {"no_such_key": 1}})


def test_dotted_setter_names_the_replacement():
    with pytest.raises(ConfigError, match="use arm.sections.1.stiffness_scale instead"):
        replace_path(ScenarioConfig(), "model.section_stiffness_scale.1", 1.5)


def test_sweep_grid_path_names_the_replacement():
    from continuum_sim.sweep.spec import parse_spec

    data = {"grid": {"model.section_stiffness_scale.0": [0.5, 1.0]}, "evaluation": {"kind": "gravity_sag"}}
    with pytest.raises(ConfigError) as info:
        parse_spec(data)
    assert str(info.value).startswith("grid.model.section_stiffness_scale.0: removed; use arm.sections.0.stiffness_scale")


def test_optimize_variable_names_the_replacement():
    from continuum_sim.optimize.spec import parse_spec

    text = (
        '[variables]\n"model.section_stiffness_scale.1" = {low = 0.5, high = 2.0}\n'
        '[[objectives]]\nmetric = "sag_mm"\n[evaluation]\nkind = "gravity_sag"\n'
    )
    with pytest.raises(ConfigError) as info:
        parse_spec(tomllib.loads(text))
    assert "use arm.sections.1.stiffness_scale instead" in str(info.value)


def test_optimize_spec_config_table_names_the_replacement():
    from continuum_sim.optimize.spec import parse_spec

    text = (
        '[config.model]\nsection_stiffness_scale = [1.0, 1.0, 1.0]\n'
        '[variables]\n"control.pretension" = {low = 15.0, high = 50.0}\n'
        '[[objectives]]\nmetric = "sag_mm"\n[evaluation]\nkind = "gravity_sag"\n'
    )
    with pytest.raises(ConfigError, match=REPLACEMENT.replace(".", r"\.")):
        parse_spec(tomllib.loads(text))


def test_sensitivity_parameter_names_the_replacement():
    pytest.importorskip("SALib")
    from continuum_sim.sensitivity.spec import parse_spec

    with pytest.raises(ConfigError, match="use arm.sections.2.stiffness_scale instead"):
        parse_spec(tomllib.loads('parameters = ["model.section_stiffness_scale.2"]\n'))


def test_cli_run_prints_one_line_and_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[model]\nsection_stiffness_scale = [1.0, 1.2, 0.9]\n")
    assert main(["run", "--config", str(bad), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and REPLACEMENT in err and "model.section_stiffness_scale" in err
