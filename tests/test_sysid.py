"""Sim-to-real (issue 15): recorded-data format, replay, synthetic identification, CLI refusals.

The synthetic case is the identification's own test (SPEC §11): data made by the model
with hidden parameter values and 0.2 mm / 0.2° noise must give those values back.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from continuum_sim.cli import main
from continuum_sim.configio import ConfigError, replace_path
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.sysid.data import (
    format_recording,
    parse_recording,
    read_recording,
    write_recording,
)
from continuum_sim.sysid.excitation import synthesize
from continuum_sim.sysid.identify import identify, parse_fit
from continuum_sim.sysid.replay import replay_metrics, simulate

HIDDEN = {"model.stiffness_scale": 1.3, "model.rope_modulus": 55.0e9, "model.grinder_mass": 0.11}
NOISE_MM, NOISE_DEG = 0.2, 0.2
# RMS of the 3-D position error of isotropic noise σ per axis: √3·σ.
NOISE_RMSE_MM = math.sqrt(3.0) * NOISE_MM


@pytest.fixture(scope="module")
def base() -> ScenarioConfig:
    # Elastic cables (EA/L) whatever the shipped default: the rope modulus is a hidden parameter.
    # Frictionless, so the Jacobian's replays batch on threads (friction replays run one by one;
    # test_cable_friction_acts_inside_the_batched_replay covers them).
    config = replace_path(ScenarioConfig(), "model.cable_model", "elastic")
    return replace_path(config, "model.cable_friction.mu", 0.0)


@pytest.fixture(scope="module")
def truth(base: ScenarioConfig) -> ScenarioConfig:
    config = base
    for path, value in HIDDEN.items():
        config = replace_path(config, path, value)
    return config


@pytest.fixture(scope="module")
def recording(truth: ScenarioConfig, tmp_path_factory) -> Path:
    rec = synthesize(truth, "left", duration=8.0, rate_hz=20.0, noise_mm=NOISE_MM, noise_deg=NOISE_DEG, seed=3, amplitude=0.4)
    return write_recording(rec, tmp_path_factory.mktemp("sysid") / "synthetic.csv")


def test_identify_recovers_hidden_parameters(base: ScenarioConfig, recording: Path) -> None:
    rec = read_recording(recording)
    params = [parse_fit(path, base) for path in HIDDEN]
    result = identify(base, rec, params, nthread=2, max_nfev=25)
    report = result.report
    for path, true in HIDDEN.items():
        assert report["parameters"][path] == pytest.approx(true, rel=0.05), path
        assert report["details"][path]["identifiable"], report["details"][path]["why_not"]
    assert report["rmse_before_mm"] > 10 * NOISE_RMSE_MM
    assert 0.8 * NOISE_RMSE_MM < report["rmse_after_mm"] < 1.2 * NOISE_RMSE_MM
    # The fitted configuration is the starting one with only the fitted fields changed.
    for path, value in report["parameters"].items():
        assert replace_path(base, path, value) is not None


def test_replay_true_parameters_reproduce_noise_level_wrong_ones_do_not(base: ScenarioConfig, truth: ScenarioConfig,
                                                                      recording: Path) -> None:
    rec = read_recording(recording)
    good, wrong = simulate([truth, base], rec, nthread=2)
    m_good, m_wrong = replay_metrics(good, rec), replay_metrics(wrong, rec)
    assert 0.8 * NOISE_RMSE_MM < m_good["position_error_mm"]["rms"] < 1.2 * NOISE_RMSE_MM
    # Orientation noise: a Gaussian rotation vector with σ per axis has RMS angle √3·σ.
    assert 0.8 * math.sqrt(3) * NOISE_DEG < m_good["orientation_error_deg"]["rms"] < 1.2 * math.sqrt(3) * NOISE_DEG
    assert m_good["tension_error_n"]["max"] < 1e-9  # synthesised tensions are noise-free
    assert m_wrong["position_error_mm"]["rms"] > 10 * m_good["position_error_mm"]["rms"]


def test_unidentifiable_parameter_is_reported(base: ScenarioConfig, recording: Path) -> None:
    """The lumped servo gain does nothing with elastic cables: the fit must say so."""
    rec = read_recording(recording).subset(np.arange(0, 60))
    params = [parse_fit("model.stiffness_scale", base), parse_fit("model.cable_kp", base)]
    report = identify(base, rec, params, max_nfev=3).report
    assert "model.cable_kp" in report["unidentifiable"]
    assert "cannot move it" in report["details"]["model.cable_kp"]["why_not"]  # zero column of J


def test_format_round_trip_and_motor_columns(recording: Path) -> None:
    rec = read_recording(recording)
    again = parse_recording(format_recording(rec))
    np.testing.assert_array_equal(again.commands, rec.commands)
    np.testing.assert_array_equal(again.position, rec.position)
    # Motor angles: Δl = angle · spool radius.
    text = format_recording(rec).replace("left/cable_", "left/motor_")
    motor = parse_recording(text, spool_radius=0.5)
    np.testing.assert_allclose(motor.commands, 0.5 * rec.commands)


def test_shipped_example_reads() -> None:
    rec = read_recording(Path(__file__).resolve().parents[1] / "docs" / "sysid" / "example_recording.csv")
    assert rec.quaternion is not None and rec.tensions is not None and rec.measured.all()


def test_sparse_rates_interpolate_commands_and_skip_missing_poses() -> None:
    cables = ",".join(f"left/cable_{k}_{c}" for k in range(3) for c in range(3))
    text = (f"time,{cables},left/tool_x,left/tool_y,left/tool_z\n"
            f"0.0,{','.join(['0'] * 9)},0,0,0.6\n"
            f"0.5,{','.join([''] * 9)},,,\n"
            f"1.0,{','.join(['-0.002'] * 9)},0,0,0.6\n")
    rec = parse_recording(text)
    np.testing.assert_allclose(rec.commands[1], -0.001)
    assert rec.measured.tolist() == [True, False, True]


BAD_FILES = {
    "no time column": ("left/cable_0_0\n1\n", "missing column 'time'"),
    "text in a number": (None, "row {second}, column 'left/cable_1_2'"),
    "time going back": (None, "row {third}, column 'time'"),
    "unknown column": ("time,left/cable_0_0,left/bogus\n", "'left/bogus'"),
    "partial pose": (None, "tool_x, tool_y, tool_z"),
}


def _bad_text(kind: str, good: str) -> str:
    lines = good.splitlines()
    header_at = next(i for i, line in enumerate(lines) if line.startswith("time,"))
    header = lines[header_at].split(",")
    if kind == "text in a number":
        row = lines[header_at + 2].split(",")
        row[header.index("left/cable_1_2")] = "abc"
        lines[header_at + 2] = ",".join(row)
    elif kind == "time going back":
        row = lines[header_at + 3].split(",")
        row[0] = "-1"
        lines[header_at + 3] = ",".join(row)
    elif kind == "partial pose":
        row = lines[header_at + 1].split(",")
        row[header.index("left/tool_y")] = ""
        lines[header_at + 1] = ",".join(row)
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("kind", sorted(BAD_FILES))
def test_bad_data_file_is_one_line_exit_2(kind: str, recording: Path, tmp_path: Path, capsys) -> None:
    text, expected = BAD_FILES[kind]
    if text is None:
        text = _bad_text(kind, recording.read_text())
        header_line = 1 + next(i for i, line in enumerate(text.splitlines()) if line.startswith("time,"))
        expected = expected.format(second=header_line + 2, third=header_line + 3)  # rows are file lines
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    with pytest.raises(ConfigError) as info:
        read_recording(bad)
    assert expected in str(info.value)
    assert main(["replay", str(bad), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expected in err


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["identify", "DATA", "--fit", "model.stifness_scale"], "model.stifness_scale"),
        (["identify", "DATA", "--fit", "model.stiffness_scale=-1:2"], "bound -1"),
        (["identify", "DATA", "--fit", "model.joint"], "not a numeric field"),
        (["synthesize", "--set", "model.stiffness_scale=-1", "--out", "OUT/x.csv"], "model.stiffness_scale"),
        (["synthesize", "--set", "arm.nope=1", "--out", "OUT/x.csv"], "arm.nope"),
    ],
)
def test_bad_paths_and_values_are_one_line_exit_2(argv: list[str], expected: str, recording: Path, tmp_path: Path,
                                                  capsys) -> None:
    argv = [str(recording) if a == "DATA" else a.replace("OUT", str(tmp_path)) for a in argv]
    if argv[0] == "identify":
        argv += ["--out", str(tmp_path / "id"), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expected in err, err


def test_cli_replay_writes_run_folder(recording: Path, tmp_path: Path, capsys) -> None:
    assert main(["replay", str(recording), "--out", str(tmp_path / "rp")]) == 0
    metrics = json.loads((tmp_path / "rp" / "replay.json").read_text())
    assert metrics["samples"] > 100
    for name in ("config.toml", "trajectory.npz", "plots/tool_paths.png"):
        assert (tmp_path / "rp" / name).is_file(), name


def test_cable_friction_acts_inside_the_batched_replay(base: ScenarioConfig, recording: Path) -> None:
    """The replay runs in mujoco.rollout; friction (a passive callback) must act there as in mj_step."""
    import mujoco

    from continuum_sim.configio import get_path
    from continuum_sim.plant.friction import install_cable_friction
    from continuum_sim.sysid.plant import build_replay_model, control_matrix

    try:
        get_path(base, "model.cable_friction.mu")
    except ConfigError:
        pytest.fail("model.cable_friction.mu is not a config path")
    rec = read_recording(recording).subset(np.arange(0, 12))
    rec.info = dataclasses.replace(rec.info, mode="quasi_static", settle_s=0.1)
    with_mu = replace_path(base, "model.cable_friction.mu", 0.3)
    plant = build_replay_model(with_mu, rec.arm, rec.info.tool, rec.info.gravity)
    (replayed,) = simulate([with_mu], rec, plants=[plant])
    (frictionless,) = simulate([replace_path(base, "model.cable_friction.mu", 0.0)], rec)
    model = plant.model
    data = mujoco.MjData(model)
    handle = install_cable_friction(model, data, with_mu.model.cable_friction)
    settle = round(0.1 / model.opt.timestep)
    tips = []
    for row in control_matrix(with_mu, plant, rec.commands, rec.gripper, rec.spindle):
        data.ctrl[:] = row
        for _ in range(settle - 1):
            mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)
        tips.append(data.sensordata[plant.sensor_pos].copy())
        mujoco.mj_step(model, data)
    handle.uninstall()
    np.testing.assert_allclose(replayed.position, np.array(tips), atol=1e-12)
    assert np.abs(replayed.position - frictionless.position).max() > 1e-5
