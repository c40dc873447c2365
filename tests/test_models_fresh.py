"""The committed models/ files are what `continuum-sim build-model` generates now."""

from pathlib import Path

import pytest

from continuum_sim.cli import main
from continuum_sim.model.export import ARM_FILE, DUAL_ARM_FILE, model_xml_texts
from continuum_sim.scenario.config import ScenarioConfig

import mujoco  # noqa: E402  (export imported the scene, which chose the GL backend)

MODELS = Path(__file__).resolve().parent.parent / "models"


@pytest.fixture(scope="module")
def fresh() -> dict[str, str]:
    defaults = ScenarioConfig.default()
    return model_xml_texts(defaults.arm, defaults.layout, defaults.model, defaults.scene)


@pytest.mark.parametrize("name", [DUAL_ARM_FILE, ARM_FILE])
def test_committed_model_is_fresh(fresh, name):
    committed = MODELS / name
    assert committed.exists(), f"models/{name} missing: run `continuum-sim build-model`"
    assert committed.read_text() == fresh[name], f"models/{name} is stale: run `continuum-sim build-model`"


@pytest.mark.parametrize("name", [DUAL_ARM_FILE, ARM_FILE])
def test_committed_model_loads_with_plain_mujoco(name):
    model = mujoco.MjModel.from_xml_path(str(MODELS / name))
    assert model.ntendon >= 9 and model.nu >= 9


def test_build_model_cli_writes_the_same_files(tmp_path, fresh, capsys):
    assert main(["build-model", "--out", str(tmp_path), "--models-only"]) == 0
    for name in (DUAL_ARM_FILE, ARM_FILE):
        assert (tmp_path / name).read_text() == fresh[name]
    assert "wrote" in capsys.readouterr().out


def test_build_model_cli_bad_config_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[model]\nsegments_per_section = -1\n")
    assert main(["build-model", "--out", str(tmp_path), "--config", str(bad)]) == 2
    assert "segments_per_section" in capsys.readouterr().err


def test_committed_scene_is_the_model_run_simulates(fresh):
    """models/dual_arm.xml = the scene `continuum-sim run` compiles from the shipped defaults."""
    from continuum_sim.model.export import PRECISION, ZERO_THRESHOLD
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.runner import build_scene_model

    config = ScenarioConfig.default()
    root, model = build_scene_model(config)
    assert root.to_xml_string(precision=PRECISION, zero_threshold=ZERO_THRESHOLD) == fresh[DUAL_ARM_FILE]
    committed = mujoco.MjModel.from_xml_path(str(MODELS / DUAL_ARM_FILE))
    assert committed.opt.timestep == config.model.timestep == model.opt.timestep
    assert (committed.nq, committed.nv, committed.nu, committed.ngeom) == (model.nq, model.nv, model.nu, model.ngeom)
