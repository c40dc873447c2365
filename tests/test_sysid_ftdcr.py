"""FTDCR v4 importer (validation/opencr_ftdcr_v4): conventions checked against upstream's own facts."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from continuum_sim.sysid.data import format_recording, read_recording
from continuum_sim.sysid.ftdcr import import_ftdcr, read_upstream, tendon_angles_deg

FOLDER = Path(__file__).resolve().parents[1] / "validation" / "opencr_ftdcr_v4"
PULL = FOLDER / "ftdcr_v4_tendon_pull.csv"

# Upstream's calibration of the same robot (configs/generation/ftdcr_v4_sysid.json, commit
# 17fff8b): tendon angle = seg_offset + t·120° + delta_t, from its own geometric step.
UPSTREAM_OFFSETS = np.array([-3.0589, -2.5615, -2.0506])
UPSTREAM_DELTAS = np.array([[0.0092, 0.1303, -0.1395], [0.1411, -0.1228, -0.0183], [-0.1351, 0.0243, 0.1108]])


def test_tendon_angles_agree_with_upstream_calibration() -> None:
    _, labels, servo, s, tip = read_upstream(PULL)
    ours = tendon_angles_deg(labels, servo, s, tip)
    theirs = np.degrees(UPSTREAM_OFFSETS[:, None] + np.arange(3)[None, :] * 2 * np.pi / 3 + UPSTREAM_DELTAS)
    diff = (ours - theirs + 180.0) % 360.0 - 180.0
    assert np.abs(diff).max() < 10.0, diff


def test_import_conventions() -> None:
    rec = import_ftdcr(FOLDER / "ftdcr_v4_train.csv", PULL)
    assert len(rec.time) == 1620 and rec.n_cables == 9
    assert rec.info.mode == "quasi_static" and rec.info.align == "offset" and not rec.info.gravity
    # Row 11 of the first pull (tendon 0 = servo 4 at +4.17 mm): reeled in, the others released to -10 mm.
    np.testing.assert_allclose(rec.commands[10, 0], -4.172428e-3)
    np.testing.assert_allclose(rec.commands[10, 1:], 9.99e-3, atol=4e-5)
    # The neutral tip sits on the z axis, near the robot's 186.5 mm length (+ marker).
    assert np.linalg.norm(rec.position[0, :2]) < 2e-3 and 0.185 < rec.position[0, 2] < 0.190


def test_shipped_conversions_are_fresh() -> None:
    for name in ("tendon_pull", "train", "val"):
        shipped = read_recording(FOLDER / f"ftdcr_v4_{name}.recording.csv")
        fresh = import_ftdcr(FOLDER / f"ftdcr_v4_{name}.csv", PULL)
        assert format_recording(shipped) == format_recording(fresh), f"rerun `python -m continuum_sim.sysid.ftdcr` ({name})"
