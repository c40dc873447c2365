"""FTDCR v4 through the general OpenCR importer (validation/opencr_ftdcr_v4): conventions checked against upstream's facts."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from continuum_sim.sysid.data import format_recording, read_recording
from continuum_sim.sysid.opencr import import_folder, read_session, tendon_angles_deg
from continuum_sim.sysid.robot import import_robot

FOLDER = Path(__file__).resolve().parents[1] / "validation" / "opencr_ftdcr_v4"
PULL = FOLDER / "ftdcr_v4_tendon_pull.csv"

# Upstream's calibration of the same robot (configs/generation/ftdcr_v4_sysid.json, commit
# 17fff8b): tendon angle = seg_offset + t·120° + delta_t, from its own geometric step.
UPSTREAM_OFFSETS = np.array([-3.0589, -2.5615, -2.0506])
UPSTREAM_DELTAS = np.array([[0.0092, 0.1303, -0.1395], [0.1411, -0.1228, -0.0183], [-0.1351, 0.0243, 0.1108]])


def _upstream_deg() -> np.ndarray:
    return np.degrees(UPSTREAM_OFFSETS[:, None] + np.arange(3)[None, :] * 2 * np.pi / 3 + UPSTREAM_DELTAS)


def test_tendon_angles_agree_with_upstream_calibration() -> None:
    s = read_session(PULL)
    ours = tendon_angles_deg(s.labels, s.tip, 9)
    diff = (ours - _upstream_deg() + 180.0) % 360.0 - 180.0
    assert np.abs(diff).max() < 10.0, diff


def test_robot_json_angles_are_upstreams_formula() -> None:
    _, config = import_robot(FOLDER / "ftdcr_v4_sysid.json")
    ours = np.array([s["cable_angles_deg"] for s in config["arm"]["sections"]])
    diff = (ours - _upstream_deg() + 180.0) % 360.0 - 180.0
    assert np.abs(diff).max() < 1e-3
    # per-segment pretension (0.0006, 1.16, 3.87 N): the smallest global, the rest per section
    assert abs(config["control"]["pretension"] - 0.0005778742714404039) < 1e-12
    np.testing.assert_allclose([s["extra_pretension"] for s in config["arm"]["sections"]], [0.0, 1.15994, 3.87411], atol=1e-4)


def test_import_conventions_and_fresh_shipped_recordings(tmp_path: Path) -> None:
    written, notes, _ = import_folder(FOLDER, tmp_path)
    assert sorted(written) == ["tendon_pull", "train", "val"]
    rec = read_recording(written["train"])
    assert len(rec.time) == 1620 and rec.n_cables == 9
    assert rec.info.mode == "quasi_static" and rec.info.align == "offset" and not rec.info.gravity
    assert rec.info.source.startswith("ftdcr_v4 (") and "FTDCR v4" not in rec.info.source
    # Row 11 of the first pull (tendon 0 = servo 4 at +4.17 mm): reeled in, the others released to -10 mm.
    np.testing.assert_allclose(rec.commands[10, 0], -4.172428e-3)
    np.testing.assert_allclose(rec.commands[10, 1:], 9.99e-3, atol=4e-5)
    # The neutral tip sits on the z axis, near the robot's 186.5 mm length (+ marker).
    assert np.linalg.norm(rec.position[0, :2]) < 2e-3 and 0.185 < rec.position[0, 2] < 0.190
    for kind, path in written.items():
        shipped = read_recording(FOLDER / "recordings" / f"{kind}.recording.csv")
        assert format_recording(shipped) == format_recording(read_recording(path)), (
            f"rerun `continuum-sim import-recording {FOLDER} --out {FOLDER}/recordings --robot ...` ({kind})")
