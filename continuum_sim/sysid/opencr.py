"""Importer of OpenCR-style motion-capture sessions (any tendon-driven robot of that family).

A session folder holds CSV files with the header ``timestamp`` (Unix s), ``pattern_label``,
one ``servo_<id>_mm`` column per tendon (tendon displacement, mm) and ``tip_x/y/z`` (mm).
File names do not matter: each CSV's kind comes from its header and its labels —

* ``tendon_pull``: every row is a single-tendon pull ``rep<N>_tendon<X>_id<Y>_pull`` (or its ``_hold``);
* ``train``: pull rows and motion patterns;
* ``val``: motion patterns only (no pull rows);
* ``session``: the whole session, i.e. its time stamps contain a pattern file's (written
  only when nothing else covers it); a CSV without the OpenCR header is skipped (named).

Conventions (from the OpenCR-MuJoCo repository, ContinuumRoboticsLab/opencr-mujoco @ 17fff8b,
``sysid/pipeline_data_loader.py``, ``trajectory_simulator.py``, ``geometric_identifier.py``;
facts, not code): tendon index X = M·section + tendon, sections base→tip; the pull label
says tendon X is driven by servo Y (else the columns are taken in tendon order); a
positive servo value pulls its tendon, Δl = −servo/1000 m; a pulled tendon bends the robot
toward itself, so the tip's deflection direction in a single pull is that tendon's angle
about the backbone; the neutral tip is the mean first sample of the pulls; the capture
z axis runs along the straight robot. The recording's world frame is the capture frame
shifted so the robot's axis is the z axis: the neutral marker lies at the marker offset's
(x, y) (``--marker-offset``, in the tip frame; default 0). The number of sections N is
(servo columns)/M with M = 3 tendons per section (the model's; a robot JSON's
``number_of_tendons`` is checked against it).
"""

from __future__ import annotations

import csv
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..configio import ConfigError
from .data import Recording, RecordingInfo, write_recording

Array = NDArray[np.float64]
PULL = re.compile(r"^rep\d+_tendon(\d+)_id(\d+)_pull$")
PULL_ROW = re.compile(r"^rep\d+_tendon\d+_id\d+_pull(_hold)?$")  # a pull or its hold
SERVO = re.compile(r"^servo_(\d+)_mm$")
TENDONS_PER_SECTION = 3
KINDS = ("tendon_pull", "train", "val", "session")


@dataclass
class Session:
    """One OpenCR session CSV as arrays (servo columns in file order)."""

    path: Path
    time: Array  # (N,) Unix s
    labels: list[str]
    servo: list[str]  # column names
    commands: Array  # (N, S) mm
    tip: Array  # (N, 3) mm

    @property
    def pulls(self) -> NDArray[np.bool_]:
        return np.array([PULL_ROW.match(label) is not None for label in self.labels])


def is_session_header(header: list[str]) -> bool:
    need = {"timestamp", "pattern_label", "tip_x", "tip_y", "tip_z"}
    return need <= set(header) and any(SERVO.match(h) for h in header)


def read_session(path: str | os.PathLike[str]) -> Session:
    """The session CSV at ``path``; one ``ConfigError`` line naming the file and row on bad input."""
    where = str(path)
    try:
        rows = list(csv.reader(Path(path).read_text().splitlines()))
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(where, f"cannot read ({getattr(exc, 'strerror', None) or exc})") from None
    if not rows or not is_session_header([h.strip() for h in rows[0]]):
        raise ConfigError(where, "not an OpenCR session CSV (header needs timestamp, pattern_label, servo_<id>_mm ..., "
                                 "tip_x, tip_y, tip_z)")
    header = [h.strip() for h in rows[0]]
    servo = [h for h in header if SERVO.match(h)]
    body = [(i + 2, r) for i, r in enumerate(rows[1:]) if any(c.strip() for c in r)]
    if len(body) < 2:
        raise ConfigError(where, f"needs at least 2 data rows (got {len(body)})")
    cols = {name: header.index(name) for name in header}
    t, s, tip, labels = [], [], [], []
    for row_no, r in body:
        if len(r) != len(header):
            raise ConfigError(f"{where}: row {row_no}", f"has {len(r)} cells, the header has {len(header)}")
        try:
            t.append(float(r[cols["timestamp"]]))
            s.append([float(r[cols[c]]) for c in servo])
            tip.append([float(r[cols[c]]) for c in ("tip_x", "tip_y", "tip_z")])
        except ValueError as exc:
            raise ConfigError(f"{where}: row {row_no}", f"not a number ({exc})") from None
        labels.append(r[cols["pattern_label"]].strip())
    time = np.array(t)
    back = np.flatnonzero(np.diff(time) <= 0)
    if back.size:
        raise ConfigError(f"{where}: row {body[back[0] + 1][0]}", "timestamp must increase strictly")
    arr = np.array(s), np.array(tip)
    if not (np.all(np.isfinite(arr[0])) and np.all(np.isfinite(arr[1]))):
        raise ConfigError(where, "servo and tip values must be finite")
    return Session(Path(path), time, labels, servo, arr[0], arr[1])


def classify(sessions: list[Session]) -> dict[Path, str]:
    """The kind of each session (module docstring), from its labels and time stamps."""
    stamps = [set(np.round(s.time, 6).tolist()) for s in sessions]
    kinds: dict[Path, str] = {}
    for i, s in enumerate(sessions):
        covers = any(j != i and stamps[j] < stamps[i] and not sessions[j].pulls.all() for j in range(len(sessions)))
        pulls = s.pulls
        if covers:
            kinds[s.path] = "session"
        elif pulls.all():
            kinds[s.path] = "tendon_pull"
        elif pulls.any():
            kinds[s.path] = "train"
        else:
            kinds[s.path] = "val"
    return kinds


def tendon_order(s: Session) -> list[int]:
    """Column index of each tendon 0..S-1: from the pull labels where they name every servo, else file order."""
    mapping: dict[int, int] = {}
    for label in s.labels:
        m = PULL.match(label)
        if m:
            mapping.setdefault(int(m.group(1)), int(m.group(2)))
    if sorted(mapping) == list(range(len(s.servo))) and all(f"servo_{y}_mm" in s.servo for y in mapping.values()):
        return [s.servo.index(f"servo_{mapping[x]}_mm") for x in range(len(s.servo))]
    return list(range(len(s.servo)))


def section_count(n_servo: int, tendons_per_section: int = TENDONS_PER_SECTION) -> int:
    if tendons_per_section != TENDONS_PER_SECTION:
        raise ConfigError("number_of_tendons", f"the model drives every section with 3 tendons (got {tendons_per_section})")
    if n_servo % TENDONS_PER_SECTION or n_servo == 0:
        raise ConfigError("servo columns", f"{n_servo} servo_<id>_mm columns are not N sections x 3 tendons")
    return n_servo // TENDONS_PER_SECTION


def neutral_tip(pull: Session) -> Array:
    """Mean of the first sample of every single-tendon pull (mm): the straight robot's marker."""
    firsts, seen = [], set()
    for i, label in enumerate(pull.labels):
        if PULL.match(label) and label not in seen:
            seen.add(label)
            firsts.append(pull.tip[i])
    if not firsts:
        raise ConfigError(str(pull.path), "no rep<N>_tendon<X>_id<Y>_pull rows to find the neutral tip")
    return np.mean(firsts, axis=0)


def tendon_angles_deg(labels: list[str], tip: Array, n_tendons: int) -> Array:
    """(N, 3) angle of each tendon about the backbone (deg) from single-tendon pull rows.

    The direction of the largest tip deflection from the pull's first sample, averaged over
    repetitions (circular mean); NaN for a tendon without a pull.
    """
    sums = np.zeros((n_tendons, 2))
    for label in sorted(set(labels)):
        m = PULL.match(label)
        if not m or int(m.group(1)) >= n_tendons:
            continue
        rows = [i for i, lab in enumerate(labels) if lab == label]
        xy = tip[rows, :2] - tip[rows[0], :2]
        peak = int(np.argmax(np.linalg.norm(xy, axis=1)))
        sums[int(m.group(1))] += xy[peak] / max(float(np.linalg.norm(xy[peak])), 1e-12)
    angles = np.degrees(np.arctan2(sums[:, 1], sums[:, 0]))
    angles[np.linalg.norm(sums, axis=1) == 0] = np.nan
    return angles.reshape(-1, TENDONS_PER_SECTION)


def to_recording(s: Session, neutral: Array, source: str, settle_s: float = 0.3,
                 marker_offset: tuple[float, float, float] = (0.0, 0.0, 0.0), arm: str = "left",
                 servo_names: list[str] | None = None) -> Recording:
    """The session as a recording of ``arm`` (capture frame shifted so the robot's axis is z).

    ``servo_names``: the servo column of each tendon 0..S-1 (from the pull file's labels: a
    file without pulls cannot tell); default: this file's own labels, else its column order.
    """
    order = tendon_order(s) if servo_names is None else [s.servo.index(n) for n in servo_names]
    delta = -s.commands[:, order] / 1000.0
    shift = np.array([neutral[0] / 1000.0 - marker_offset[0], neutral[1] / 1000.0 - marker_offset[1], 0.0])
    pos = s.tip / 1000.0 - shift
    try:
        info = RecordingInfo(mode="quasi_static", settle_s=float(settle_s), gravity=False, tool="none", align="offset",
                             source=source)
    except ConfigError as exc:
        raise exc.under("--settling-time: ") from None
    return Recording(arm, s.time - s.time[0], delta, pos, None, None, None, None, list(s.labels), info)


def source_name(folder: Path, files: list[Path]) -> str:
    """The data's name: the files' common stem prefix (``tdcr_sysid_20260511``), else the folder's name."""
    prefix = os.path.commonprefix([f.stem for f in files]).rstrip("_-. ")
    return prefix if len(prefix) >= 3 else folder.resolve().name


def import_folder(folder: str | os.PathLike[str], out: str | os.PathLike[str], settle_s: float = 0.3,
                  marker_offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
                  tendons_per_section: int = TENDONS_PER_SECTION, sections: int | None = None
                  ) -> tuple[dict[str, Path], list[str], Array]:
    """Convert every session CSV in ``folder`` into ``out/<kind>.recording.csv``.

    Returns (kind → written file, notes on skipped files, tendon angles (N, 3) deg from the pulls).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError(str(folder), "not a folder (give the session folder holding the CSV files)")
    notes: list[str] = []
    sessions: list[Session] = []
    for path in sorted(folder.glob("*.csv")):
        try:
            head = next(csv.reader([path.read_text(errors="replace").split("\n", 1)[0]]), [])
        except OSError:
            head = []
        if is_session_header([h.strip() for h in head]) and not path.name.endswith(".recording.csv"):
            sessions.append(read_session(path))
        else:
            notes.append(f"skipped {path.name} (not an OpenCR session CSV)")
    if not sessions:
        raise ConfigError(str(folder), "holds no OpenCR session CSV (header timestamp, pattern_label, servo_<id>_mm ..., tip_x/y/z)")
    columns = {tuple(sorted(s.servo)) for s in sessions}
    if len(columns) != 1:
        raise ConfigError(str(folder), "the session CSVs have different servo columns (one robot per folder)")
    n_sections = section_count(len(sessions[0].servo), tendons_per_section)
    if sections is not None and sections != n_sections:
        raise ConfigError("--robot", f"describes {sections} sections, the data have {len(sessions[0].servo)} servo columns "
                                     f"= {n_sections} sections x 3 tendons")
    kinds = classify(sessions)
    pulls = [s for s in sessions if kinds[s.path] == "tendon_pull"] or [s for s in sessions if s.pulls.any()]
    if not pulls:
        raise ConfigError(str(folder), "no single-tendon pull rows (rep<N>_tendon<X>_id<Y>_pull) to find the neutral tip")
    pull = pulls[0]
    neutral = neutral_tip(pull)
    angles = tendon_angles_deg(pull.labels, pull.tip, len(pull.servo))
    servo_names = [pull.servo[i] for i in tendon_order(pull)]  # the same mapping for every file
    name = source_name(folder, [s.path for s in sessions])
    out = Path(out)
    written: dict[str, Path] = {}
    others = [s for s in sessions if kinds[s.path] != "session"]
    for s in sessions:
        kind = kinds[s.path]
        if kind == "session" and others:
            notes.append(f"skipped {s.path.name} (the whole session; its parts are converted)")
            continue
        key = kind if kind not in written else f"{kind}_{s.path.stem}"
        rec = to_recording(s, neutral, f"{name} ({s.path.name}, {kind}), imported by continuum-sim import-recording",
                           settle_s, marker_offset, servo_names=servo_names)
        written[key] = write_recording(rec, out / f"{key}.recording.csv", (
            f"OpenCR session {name}: {s.path.name} ({kind}; {n_sections} sections x 3 tendons)",
            f"neutral marker from {pull.path.name}: ({neutral[0]:.3f}, {neutral[1]:.3f}, {neutral[2]:.3f}) mm",
            "converted by `continuum-sim import-recording` (docs/sysid.md)"))
    return written, notes, angles
