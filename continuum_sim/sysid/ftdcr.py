"""Importer of the OpenCR-MuJoCo FTDCR v4 motion-capture recordings (validation/opencr_ftdcr_v4/).

Upstream format (its README): ``timestamp`` (Unix s), ``pattern_label``, nine
``servo_<id>_mm`` (tendon displacement per servo, mm), ``tip_x/y/z`` (mm). Conventions
taken from the upstream repository (ContinuumRoboticsLab/opencr-mujoco, commit 17fff8b:
``sysid/pipeline_data_loader.py``, ``sysid/trajectory_simulator.py``,
``sysid/geometric_identifier.py``; facts, not code):

* tendon index X = 3·segment + tendon, segments base→tip (60, 62.5, 64 mm); the label
  ``rep<N>_tendon<X>_id<Y>_pull`` says tendon X is driven by servo Y, and the file's
  servo columns appear in tendon order 0..8;
* a positive servo value pulls its tendon (shortens it): Δl = −servo/1000 m; −10 mm is
  the servos' "released" value (the tendon slack);
* a tendon bends the robot toward itself: the tip's deflection direction when one tendon
  is pulled alone is that tendon's angle about the backbone in the motion-capture frame
  (upstream calibrates per-segment offsets and per-tendon deltas from exactly this);
* the neutral tip (first sample of each single-tendon pull, averaged) is the marker
  bias; the motion-capture z axis runs along the straight robot.

The converted recording's world frame is the motion-capture frame shifted so the
neutral tip lies on the z axis (the arm's base at the origin, pointing +z). It is
marked ``mode = quasi_static`` (each command settled, as upstream replays it),
``gravity = false`` (as upstream's sysid model; the capture frame's level is unknown),
``tool = none`` and ``align = offset`` (upstream's metric removes the mean offset).
"""

from __future__ import annotations

import csv
import os
import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..configio import ConfigError
from .data import Recording, RecordingInfo

Array = NDArray[np.float64]
_PULL = re.compile(r"^rep\d+_tendon(\d+)_id(\d+)_pull$")


def read_upstream(path: str | os.PathLike[str]) -> tuple[Array, list[str], list[str], Array, Array]:
    """(time s, labels, servo column names, servo mm (N, 9), tip mm (N, 3)) of an upstream CSV."""
    where = str(path)
    try:
        rows = list(csv.reader(Path(path).read_text().splitlines()))
    except OSError as exc:
        raise ConfigError(where, f"cannot read ({exc.strerror or exc})") from None
    header = rows[0]
    need = ["timestamp", "pattern_label", "tip_x", "tip_y", "tip_z"]
    for name in need:
        if name not in header:
            raise ConfigError(where, f"missing upstream column {name!r}")
    servo = [h for h in header if re.fullmatch(r"servo_\d+_mm", h)]
    if len(servo) != 9:
        raise ConfigError(where, f"expected 9 servo_<id>_mm columns (got {len(servo)})")
    body = rows[1:]
    try:
        t = np.array([float(r[header.index("timestamp")]) for r in body])
        s = np.array([[float(r[header.index(c)]) for c in servo] for r in body])
        tip = np.array([[float(r[header.index(c)]) for c in ("tip_x", "tip_y", "tip_z")] for r in body])
    except (ValueError, IndexError) as exc:
        raise ConfigError(where, f"unreadable row ({exc})") from None
    labels = [r[header.index("pattern_label")] for r in body]
    return t, labels, servo, s, tip


def servo_order(labels: list[str], servo: list[str]) -> list[int]:
    """Column index of each tendon 0..8: from the pull labels where present, else the column order."""
    mapping: dict[int, int] = {}
    for label in labels:
        m = _PULL.match(label)
        if m:
            mapping.setdefault(int(m.group(1)), int(m.group(2)))
    if len(mapping) == len(servo):
        return [servo.index(f"servo_{mapping[x]}_mm") for x in range(len(servo))]
    return list(range(len(servo)))


def neutral_tip(labels: list[str], tip: Array) -> Array:
    """Mean of the first sample of every single-tendon pull (mm): the straight robot's tip."""
    firsts, seen = [], set()
    for i, label in enumerate(labels):
        if _PULL.match(label) and label not in seen:
            seen.add(label)
            firsts.append(tip[i])
    if not firsts:
        raise ConfigError("tendon pull", "no rep<N>_tendon<X>_id<Y>_pull rows to find the neutral tip")
    return np.mean(firsts, axis=0)


def tendon_angles_deg(labels: list[str], servo: list[str], s: Array, tip: Array) -> Array:
    """(3, 3) angle of each tendon about the backbone (deg), from single-tendon pulls.

    The direction of the largest tip deflection from the pull's first sample, averaged
    over repetitions (circular mean).
    """
    order = servo_order(labels, servo)
    sums = np.zeros((len(order), 2))
    del s
    for label in sorted(set(labels)):
        m = _PULL.match(label)
        if not m:
            continue
        rows = [i for i, lab in enumerate(labels) if lab == label]
        xy = tip[rows, :2] - tip[rows[0], :2]
        peak = int(np.argmax(np.linalg.norm(xy, axis=1)))
        d = xy[peak] / max(np.linalg.norm(xy[peak]), 1e-12)
        sums[int(m.group(1))] += d
    del order
    return np.degrees(np.arctan2(sums[:, 1], sums[:, 0])).reshape(3, 3)


def import_ftdcr(path: str | os.PathLike[str], pull_file: str | os.PathLike[str] | None = None,
                 arm: str = "left", mount: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Recording:
    """The upstream file as a recording of ``arm`` (neutral from ``pull_file``, default: the file itself)."""
    t, labels, servo, s, tip = read_upstream(path)
    if pull_file is not None:
        _, p_labels, _, _, p_tip = read_upstream(pull_file)
        neutral = neutral_tip(p_labels, p_tip)
    else:
        neutral = neutral_tip(labels, tip)
    order = servo_order(labels, servo)
    delta = -s[:, order] / 1000.0
    pos = (tip - np.array([neutral[0], neutral[1], 0.0])) / 1000.0 + np.asarray(mount)
    info = RecordingInfo(mode="quasi_static", settle_s=0.3, gravity=False, tool="none", align="offset",
                         source=f"OpenCR-MuJoCo FTDCR v4 ({Path(path).name}, MIT), imported by continuum_sim.sysid.ftdcr")
    return Recording(arm, t - t[0], delta, pos, None, None, None, None, labels, info)


FILES = ("tendon_pull", "train", "val")


def convert_all(folder: str | os.PathLike[str] = "validation/opencr_ftdcr_v4") -> list[Path]:
    """Write ``<name>.recording.csv`` beside every upstream file (neutral from the pull file)."""
    from .data import write_recording

    folder = Path(folder)
    pull = folder / "ftdcr_v4_tendon_pull.csv"
    out = []
    for name in FILES:
        rec = import_ftdcr(folder / f"ftdcr_v4_{name}.csv", pull)
        out.append(write_recording(rec, folder / f"ftdcr_v4_{name}.recording.csv",
                                   ("FTDCR v4 motion capture (OpenCR-MuJoCo, MIT licence: LICENSE-MIT-opencr-mujoco.txt),",
                                    "converted by `python -m continuum_sim.sysid.ftdcr` (docs/sysid.md)")))
    return out


if __name__ == "__main__":
    import sys

    for written in convert_all(sys.argv[1] if len(sys.argv) > 1 else "validation/opencr_ftdcr_v4"):
        print(f"wrote {written}")
