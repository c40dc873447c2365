"""Write the synthetic TDCR-3 session (OpenCR-style CSVs) that tests the import → identify workflow.

A second robot of the FTDCR family that nobody recorded: ``robot.json`` (3 sections x 3
tendons, rod backbone, 30 mm distal section), simulated by this package with hidden
"true" values the robot description does not know, then written the way an OpenCR
session is (Unix time stamps, shuffled servo ids in the column order, mm, labels):

* the capture frame is turned 25 deg about the robot axis and shifted (3, -2, 5) mm;
* the section stiffnesses are x1.35, x0.8, x1.0 of the data sheet's; section 0's tendons
  sit at 4.2 mm (data sheet 4.5 mm);
* the marker sits 10 mm beyond the tip (on the tip's z axis);
* Gaussian noise 0.2 mm per axis on the tip.

Run from the repository root: ``python validation/synthetic_tdcr3/make_session.py``
(writes ``validation/synthetic_tdcr3/session/``; seeded, so a rerun gives the same files).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from continuum_sim import kinematics as kin
from continuum_sim.configio import replace_path
from continuum_sim.model.options import model_geometry
from continuum_sim.scenario.config import ScenarioConfig, merged
from continuum_sim.sysid.data import Recording, RecordingInfo
from continuum_sim.sysid.replay import simulate
from continuum_sim.sysid.robot import import_robot

HERE = Path(__file__).resolve().parent
SERVO_IDS = [3, 1, 7, 2, 9, 4, 8, 6, 5]  # servo driving tendon 0..8
FRAME_TURN_DEG = 25.0
FRAME_SHIFT_MM = np.array([3.0, -2.0, 5.0])
NOISE_MM = 0.2
T0 = 1_790_000_000.0


def truth() -> ScenarioConfig:
    _, data = import_robot(HERE / "robot.json")
    config = merged(ScenarioConfig.default(), data)
    for k, scale in enumerate((1.35, 0.8, 1.0)):
        config = replace_path(config, f"arm.sections.{k}.stiffness_scale", scale)
        config = replace_path(config, f"arm.sections.{k}.cable_angle_offset_deg", FRAME_TURN_DEG)
    config = replace_path(config, "arm.sections.0.cable_hole_radius", 0.0042)
    return replace_path(config, "arm.tools.marker_offset.2", 0.010)


def patterns(config: ScenarioConfig) -> list[tuple[str, np.ndarray]]:
    """(label, servo mm (9,)) rows: single-tendon pulls, then section and pair bends, then all three."""
    geom = model_geometry(config.arm, config.model)
    straight = kin.straight_cable_lengths(geom)
    rows: list[tuple[str, np.ndarray]] = []
    for x in range(9):
        for mm in (0.0, 1.0, 2.0, 3.0, 4.0, 2.0, 0.0):
            s = np.zeros(9)
            s[x] = mm
            rows.append((f"rep1_tendon{x}_id{SERVO_IDS[x]}_pull", s))

    def bend(label: str, thetas: list[float], phi: float) -> None:
        for f in (0.33, 0.67, 1.0, 0.5):
            w = np.zeros(6)
            for k, th in enumerate(thetas):
                w[2 * k:2 * k + 2] = np.radians(f * th) * np.array([np.cos(phi), np.sin(phi)])
            delta = kin.cable_lengths_bending(geom, w) - straight
            rows.append((label, -1000.0 * delta))

    for d in (0, 90, 180, 270):
        phi = np.radians(d)
        for k in range(3):
            bend(f"rep1_seg{k + 1}_dir{d}", [40.0 if j == k else 0.0 for j in range(3)], phi)
        bend(f"rep1_pair12_same_dir{d}", [30.0, 30.0, 0.0], phi)
        bend(f"rep1_pair23_opp_dir{d}", [0.0, 30.0, -30.0], phi)
    for d in (45, 135, 225, 315):
        phi = np.radians(d)
        bend(f"rep1_all3_same_dir{d}", [25.0, 25.0, 25.0], phi)
        bend(f"rep1_all3_scurve_dir{d}", [25.0, -25.0, 30.0], phi)
    return rows


def main() -> None:
    config = truth()
    rows = patterns(config)
    commands = np.array([r[1] for r in rows])
    rec = Recording("left", np.arange(len(rows), dtype=float), -commands / 1000.0, np.zeros((len(rows), 3)),
                    info=RecordingInfo(mode="quasi_static", settle_s=0.3, gravity=False, tool="none", align="offset"))
    (pred,) = simulate([config], rec)
    rng = np.random.default_rng(0)
    # the model ran in the capture frame (its cable angles turned by FRAME_TURN_DEG)
    tip = pred.position * 1000.0 + FRAME_SHIFT_MM + rng.normal(0.0, NOISE_MM, pred.position.shape)
    time = T0 + 0.65 * np.arange(len(rows)) + rng.uniform(0.0, 0.05, len(rows))
    ids = sorted(SERVO_IDS)  # columns by servo id, not tendon order: the pull labels give the mapping
    cols = [SERVO_IDS.index(i) for i in ids]
    header = ["timestamp", "pattern_label", *(f"servo_{i}_mm" for i in ids), "tip_x", "tip_y", "tip_z"]
    lines = [",".join(header)] + [
        ",".join([f"{t:.6f}", label, *(f"{s[c]:.6f}" for c in cols), *(f"{v:.6f}" for v in p)])
        for t, (label, s), p in zip(time, rows, tip)]
    body = lines[1:]
    pulls = [i for i, (label, _) in enumerate(rows) if label.endswith("_pull")]
    val = [i for i, (label, _) in enumerate(rows) if "_all3_" in label]
    train = [i for i in range(len(rows)) if i not in val]
    out = HERE / "session"
    out.mkdir(exist_ok=True)
    for name, idx in (("A_pulls", pulls), ("A_motions", train), ("A_heldout", val), ("A_everything", range(len(rows)))):
        (out / f"tdcr3_{name}.csv").write_text("\n".join([lines[0], *(body[i] for i in idx)]) + "\n")
    print(f"wrote {out}: {len(rows)} rows ({len(pulls)} pulls, {len(train)} train incl. pulls, {len(val)} held out)")


if __name__ == "__main__":
    main()
