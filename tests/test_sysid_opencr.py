"""raw OpenCR-style sessions of another robot (validation/synthetic_tdcr3), robot JSON import,
per-section calibration fields, and fits that report what they could not do."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from continuum_sim.cli import main
from continuum_sim.configio import replace_path
from continuum_sim.model.cable_elasticity import cable_stiffness, pretension_offsets
from continuum_sim.model.stiffness import joint_stiffnesses
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.sysid.calibrate import calibrate_angles
from continuum_sim.sysid.data import read_recording, write_recording
from continuum_sim.sysid.replay import Prediction, marker_point

ROBOT3 = Path(__file__).resolve().parents[1] / "validation" / "synthetic_tdcr3"
# The synthetic session's hidden frame turn (make_session.py): every tendon angle + 25 deg.
TRUE_DEG = np.array([[0.0, 120.0, 240.0], [30.0, 150.0, 270.0], [60.0, 180.0, 300.0]]) + 25.0


def _wrap(a):
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("tdcr3")
    assert main(["import-recording", str(ROBOT3 / "session"), "--out", str(out), "--robot", str(ROBOT3 / "robot.json"),
                 "--settling-time", "0.25"]) == 0
    return out


def test_import_detects_kinds_sections_and_source(imported: Path, capsys) -> None:
    names = sorted(p.name for p in imported.iterdir())
    assert names == ["robot.toml", "tendon_pull.recording.csv", "train.recording.csv", "val.recording.csv"]
    val = read_recording(imported / "val.recording.csv")
    train = read_recording(imported / "train.recording.csv")
    assert val.n_cables == 9 and len(val.time) == 32 and len(train.time) == 143
    assert val.info.settle_s == 0.25 and val.info.source.startswith("tdcr3_A (tdcr3_A_heldout.csv, val)")
    # servo columns are in id order in the files; the pull labels map them back to tendon order
    pull = read_recording(imported / "tendon_pull.recording.csv")
    assert np.argmin(pull.commands[3]) == 0 and np.argmin(pull.commands[10]) == 1
    # and the held-out file (no pull labels of its own) uses the pull file's mapping
    ids = [3, 1, 7, 2, 9, 4, 8, 6, 5]  # make_session.SERVO_IDS: servo of tendon 0..8
    header, first = (ROBOT3 / "session" / "tdcr3_A_heldout.csv").read_text().splitlines()[:2]
    cells = dict(zip(header.split(","), first.split(",")))
    np.testing.assert_allclose(val.commands[0], [-float(cells[f"servo_{i}_mm"]) / 1000.0 for i in ids])
    config = ScenarioConfig.from_toml(imported / "robot.toml")
    assert config.arm.n_sections == 3 and config.arm.backbone == "rod"
    np.testing.assert_allclose([s.cable_gain_scale for s in config.arm.sections], [3.0, 3.0, 2.5])  # kp array / kp
    text = (imported / "robot.toml").read_text()
    assert "ASSUMED arm.disk_thickness" in text and "tendon_kp_array" in text


def test_calibrated_angles_match_the_hidden_frame(imported: Path) -> None:
    config = ScenarioConfig.from_toml(imported / "robot.toml")
    calibrated, info = calibrate_angles(config, read_recording(imported / "train.recording.csv"), "train")
    got = np.array([s.cable_angles_deg for s in calibrated.arm.sections])
    assert np.abs(_wrap(got - TRUE_DEG)).max() < 8.0, got
    assert info["pull_rows"] == 63


@pytest.mark.parametrize("argv, expected", [
    (["import-recording", "NOWHERE"], "not a folder"),
    (["import-recording", "EMPTY"], "no OpenCR session CSV"),
    (["import-recording", "SESSION", "--marker-offset", "1,2"], "--marker-offset"),
    (["import-recording", "SESSION", "--settling-time", "0"], "--settling-time"),
    (["import-robot", "BADJSON"], "not a JSON file"),
])
def test_import_errors_are_one_line_exit_2(argv, expected, tmp_path: Path, capsys) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "x.csv").write_text("a,b\n1,2\n")
    (tmp_path / "bad.json").write_text("{nope")
    subs = {"NOWHERE": str(tmp_path / "nowhere"), "EMPTY": str(tmp_path / "empty"), "SESSION": str(ROBOT3 / "session"),
            "BADJSON": str(tmp_path / "bad.json")}
    argv = [subs.get(a, a) for a in argv] + ["--out", str(tmp_path / "out" / "o.toml" if argv[0] == "import-robot" else tmp_path / "out")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expected in err, err


def test_per_section_calibration_fields_act_where_the_model_is_built() -> None:
    config = ScenarioConfig.default()
    arm = config.arm
    k0 = joint_stiffnesses(arm, 1, arm.sections[1].n_segments)
    c = replace_path(config, "arm.sections.1.stiffness_scale", 2.0)
    np.testing.assert_allclose(joint_stiffnesses(c.arm, 1, arm.sections[1].n_segments), 2.0 * np.array(k0))
    c = replace_path(config, "arm.sections.2.cable_gain_scale", 3.0)
    ratio = cable_stiffness(c.arm, c.model) / cable_stiffness(arm, config.model)
    np.testing.assert_allclose(ratio, [1] * 6 + [3] * 3)
    c = replace_path(config, "arm.sections.0.extra_pretension", 5.0)
    p = config.control.pretension
    np.testing.assert_allclose(pretension_offsets(c.arm, c.model, p) * cable_stiffness(arm, config.model), [p + 5] * 3 + [p] * 6)
    c = replace_path(replace_path(config, "arm.sections.0.cable_hole_radius", 0.01), "arm.sections.0.cable_angle_offset_deg", 90.0)
    holes = c.arm.cable_holes()
    np.testing.assert_allclose(np.hypot(holes[:, 0], holes[:, 1]), [0.01] * 3 + [arm.cable_hole_radius] * 6)
    np.testing.assert_allclose(holes[0, :2], [0.0, 0.01], atol=1e-12)  # 0 deg + 90 deg


def test_marker_point_rotates_with_the_tip() -> None:
    q = np.array([[np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0]])  # 90 deg about x: z -> -y
    pred = Prediction(np.zeros((1, 3)), q, np.zeros((1, 9)))
    np.testing.assert_allclose(marker_point(pred, (0.0, 0.0, 0.01)).position, [[0.0, -0.01, 0.0]], atol=1e-15)


@pytest.fixture(scope="module")
def tiny(imported: Path, tmp_path_factory) -> tuple[Path, Path]:
    """6 rows of the held-out file and the robot, frictionless: a few replays of ~1k steps."""
    rec = read_recording(imported / "val.recording.csv")
    path = write_recording(rec.subset(np.arange(0, 32, 6)), tmp_path_factory.mktemp("tiny") / "tiny.csv")
    robot = tmp_path_factory.mktemp("tiny") / "robot.toml"
    robot.write_text((imported / "robot.toml").read_text() + "\n[model.cable_friction]\nmu = 0.0\n")
    return path, robot


def _identify(tiny, tmp_path: Path, fit: str, strict: bool, extra: tuple[str, ...] = ()) -> tuple[int, dict]:
    data, robot = tiny
    argv = ["identify", str(data), "--config", str(robot), "--fit", fit, "--max-nfev", "4", "--quiet",
            "--out", str(tmp_path / "id"), *extra] + (["--strict"] if strict else [])
    code = main(argv)
    return code, json.loads((tmp_path / "id" / "report.json").read_text())


def test_fit_started_on_a_bound_is_reported_and_fails_strict(tiny, tmp_path: Path, capsys) -> None:
    code, report = _identify(tiny, tmp_path, "arm.sections.2.extra_pretension=0:5", strict=True)
    err = capsys.readouterr().err
    assert code == 1 and "started on its bound" in err and "--strict" in err
    assert any("started on its bound" in w for w in report["warnings"])


def test_fit_that_cannot_move_is_reported_and_fails_strict(tiny, tmp_path: Path, capsys) -> None:
    # The grinder's mass: no grinder rides on this robot (tool none), so nothing can move it.
    code, report = _identify(tiny, tmp_path, "model.grinder_mass", strict=False)
    err = capsys.readouterr().err
    assert code == 0 and "changed nothing" in err
    d = report["details"]["model.grinder_mass"]
    assert not d["identifiable"] and "cannot move it" in d["why_not"]
    assert report["rmse_before_mm"] == report["rmse_after_mm"]
    code, _ = _identify(tiny, tmp_path, "model.grinder_mass", strict=True)
    assert code == 1


def test_multi_start_is_seeded_sobol_and_keeps_the_best(tiny, tmp_path: Path, capsys) -> None:
    code, report = _identify(tiny, tmp_path, "arm.sections.1.stiffness_scale=0.5:2", strict=False,
                             extra=("--starts", "3", "--seed", "7"))
    runs = report["multi_start"]["runs"]
    assert code == 0 and len(runs) == 3 and runs[0]["start"] == [1.0]
    assert all(0.5 <= r["start"][0] <= 2.0 for r in runs) and len({r["start"][0] for r in runs}) == 3
    assert report["parameters"]["arm.sections.1.stiffness_scale"] == min(runs, key=lambda r: r["cost"])["end"][0]
    _, again = _identify(tiny, tmp_path, "arm.sections.1.stiffness_scale=0.5:2", strict=False,
                         extra=("--starts", "3", "--seed", "7"))
    assert [r["start"] for r in again["multi_start"]["runs"]] == [r["start"] for r in runs]  # seeded
