"""The recorded-data format: one arm's motor commands and measured tool pose over time.

A CSV file (docs/sysid.md has the schema and an example). Optional ``# key = value``
lines before the header say how the recording was made; other ``#`` lines are comments.
Columns (SI units; ``<arm>`` is ``left`` or ``right``, the arm of the layout the data
belongs to; k = section 0..n-1 base→tip, c = cable 0..2 of the section):

* ``time`` (s, strictly increasing);
* commands, one set per file: ``<arm>/cable_<k>_<c>`` = the cable set-point as a
  displacement Δl from the straight-arm length (m, negative = reeled in, SPEC §2) or
  ``<arm>/motor_<k>_<c>`` = motor angle (rad; Δl = angle · ``arm.spool_radius``);
* optional ``<arm>/tension_<k>_<c>`` (N, measured cable tension);
* ``<arm>/tool_x``, ``_y``, ``_z`` (m, tool centre point in the layout's world frame),
  optional ``<arm>/tool_qw``, ``_qx``, ``_qy``, ``_qz`` (tool frame orientation);
* optional ``<arm>/gripper`` (m, gripper cable command) and ``<arm>/spindle`` (rad/s);
* optional ``label`` (free text per row, e.g. the motion pattern).

Rates may differ: an empty command cell is interpolated linearly between the rows that
have commands; an empty pose cell means no measurement at that row. Every error is one
line naming the file, row and column.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..configio import ConfigError, atomic_write_text

Array = NDArray[np.float64]

FORMAT = "continuum-sim recording 1"
MODES = ("dynamic", "quasi_static")
TOOLS = ("auto", "none", "grinder", "gripper")


@dataclass(frozen=True)
class RecordingInfo:
    """How the recording was made (the ``# key = value`` lines).

    ``mode``: ``dynamic`` replays the commands in time; ``quasi_static`` settles every
    command for ``settle_s`` before comparing (a robot stepped slowly from pose to pose).
    ``gravity``: whether the model should feel gravity (off when the recording's world
    frame is not known to be level). ``tool``: what rides on the arm (``auto``: the tool
    of the layout's mount for this arm). ``align``: ``offset`` compares positions after
    removing the mean offset between predicted and measured (motion capture whose origin
    is not registered to the robot base), ``none`` compares them as they are.
    """

    mode: str = "dynamic"
    settle_s: float = 0.5
    gravity: bool = True
    tool: str = "auto"
    align: str = "none"
    source: str = ""

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ConfigError("mode", f"must be one of {', '.join(MODES)} (got {self.mode!r})")
        if not (isinstance(self.settle_s, float) and 0.0 < self.settle_s <= 10.0):
            raise ConfigError("settle_s", f"must satisfy 0 < settle_s <= 10 s (got {self.settle_s!r})")
        if self.tool not in TOOLS:
            raise ConfigError("tool", f"must be one of {', '.join(TOOLS)} (got {self.tool!r})")
        if self.align not in ("none", "offset"):
            raise ConfigError("align", f"must be 'none' or 'offset' (got {self.align!r})")


@dataclass
class Recording:
    """One arm's recording, as arrays (NaN marks a missing measurement)."""

    arm: str
    time: Array  # (N,) s
    commands: Array  # (N, ncables) cable displacement Δl, m (interpolated where missing)
    position: Array  # (N, 3) m, NaN rows: no measurement
    quaternion: Array | None = None  # (N, 4) w, x, y, z; NaN rows: no measurement
    tensions: Array | None = None  # (N, ncables) N
    gripper: Array | None = None  # (N,) m
    spindle: Array | None = None  # (N,) rad/s
    labels: list[str] | None = None
    info: RecordingInfo = field(default_factory=RecordingInfo)
    command_kind: str = "cable"  # how the file gave the commands: cable | motor

    @property
    def n_cables(self) -> int:
        return int(self.commands.shape[1])

    @property
    def measured(self) -> NDArray[np.bool_]:
        """Rows with a measured position."""
        return np.all(np.isfinite(self.position), axis=1)

    def subset(self, rows: NDArray[np.bool_] | NDArray[np.int_]) -> Recording:
        """The recording restricted to ``rows`` (times keep their values)."""
        def pick(a):
            return None if a is None else a[rows]
        labels = None if self.labels is None else [self.labels[i] for i in np.arange(len(self.time))[rows]]
        return Recording(self.arm, self.time[rows], self.commands[rows], self.position[rows], pick(self.quaternion),
                         pick(self.tensions), pick(self.gripper), pick(self.spindle), labels, self.info, self.command_kind)


def cable_columns(arm: str, n_sections: int, kind: str = "cable") -> list[str]:
    return [f"{arm}/{kind}_{k}_{c}" for k in range(n_sections) for c in range(3)]


POSE = ("tool_x", "tool_y", "tool_z")
QUAT = ("tool_qw", "tool_qx", "tool_qy", "tool_qz")
_META = re.compile(r"^([A-Za-z_]\w*)\s*=(.*)$")  # "# key = value"; any other "#" line is a comment
_CABLE = re.compile(r"^(left|right)/(cable|motor|tension)_(\d+)_([0-2])$")


def _parse_info(lines: list[tuple[int, str]], where: str) -> RecordingInfo:
    values: dict[str, object] = {}
    known = {"format", "mode", "settle_s", "gravity", "tool", "align", "source"}
    for row, text in lines:
        m = _META.match(text)
        if m is None:  # a comment
            continue
        key, value = m.group(1), m.group(2).strip()
        if key not in known:
            raise ConfigError(f"{where}: row {row}", f"unknown metadata key {key!r} (known: {', '.join(sorted(known))})")
        if key == "format":
            if value != FORMAT:
                raise ConfigError(f"{where}: row {row}", f"format must be {FORMAT!r} (got {value!r})")
        elif key == "settle_s":
            try:
                values[key] = float(value)
            except ValueError:
                raise ConfigError(f"{where}: row {row}", f"settle_s must be a number (got {value!r})") from None
        elif key == "gravity":
            if value.lower() not in ("true", "false"):
                raise ConfigError(f"{where}: row {row}", f"gravity must be true or false (got {value!r})")
            values[key] = value.lower() == "true"
        else:
            values[key] = value
    try:
        return RecordingInfo(**values)  # type: ignore[arg-type]
    except ConfigError as exc:
        raise exc.under(f"{where}: ") from None


def read_recording(path: str | os.PathLike[str], spool_radius: float | None = None) -> Recording:
    """Load and check a recording; every error is one ``ConfigError`` line naming row/column."""
    where = str(path)
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ConfigError(where, f"cannot read the data file ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise ConfigError(where, "not a text (UTF-8) CSV file") from None
    return parse_recording(text, where, spool_radius)


def parse_recording(text: str, where: str = "<data>", spool_radius: float | None = None) -> Recording:
    """The recording in ``text`` (see the module docstring for the format)."""
    lines = text.splitlines()
    meta: list[tuple[int, str]] = []
    start = 0
    while start < len(lines) and (lines[start].startswith("#") or not lines[start].strip()):
        if lines[start].startswith("#"):
            meta.append((start + 1, lines[start][1:].strip()))
        start += 1
    info = _parse_info(meta, where)
    rows = list(csv.reader(io.StringIO("\n".join(lines[start:]))))
    if not rows:
        raise ConfigError(where, "no header row (expected columns: time, <arm>/cable_<k>_<c> ..., <arm>/tool_x ...)")
    header = [h.strip() for h in rows[0]]
    hrow = start + 1
    seen: set[str] = set()
    for name in header:
        if name in seen:
            raise ConfigError(f"{where}: row {hrow}", f"column {name!r} appears twice")
        seen.add(name)
    if "time" not in header:
        raise ConfigError(f"{where}: row {hrow}", "missing column 'time'")
    arms = sorted({h.split("/")[0] for h in header if "/" in h})
    if len(arms) != 1 or arms[0] not in ("left", "right"):
        raise ConfigError(f"{where}: row {hrow}",
                          f"columns must belong to exactly one arm, 'left/...' or 'right/...' (found {arms or 'none'})")
    arm = arms[0]
    allowed = {"time", "label", *(f"{arm}/{p}" for p in (*POSE, *QUAT, "gripper", "spindle"))}
    groups: dict[str, dict[tuple[int, int], int]] = {"cable": {}, "motor": {}, "tension": {}}
    for j, name in enumerate(header):
        m = _CABLE.match(name)
        if m:
            groups[m.group(2)][(int(m.group(3)), int(m.group(4)))] = j
        elif name not in allowed:
            raise ConfigError(f"{where}: row {hrow}, column {name!r}",
                              "unknown column (see docs/sysid.md: time, <arm>/cable_<k>_<c> or <arm>/motor_<k>_<c>, "
                              "<arm>/tension_<k>_<c>, <arm>/tool_x..z, <arm>/tool_qw..qz, <arm>/gripper, <arm>/spindle, label)")
    if groups["cable"] and groups["motor"]:
        raise ConfigError(f"{where}: row {hrow}", "give commands as cable_<k>_<c> or motor_<k>_<c> columns, not both")
    kind = "cable" if groups["cable"] else "motor"
    cmd = groups[kind]
    if not cmd:
        raise ConfigError(f"{where}: row {hrow}", f"missing command columns {arm}/cable_<k>_<c> (or {arm}/motor_<k>_<c>)")
    n_sections = 1 + max(k for k, _ in cmd)
    for name in cable_columns(arm, n_sections, kind):
        k, c = int(name[-3]), int(name[-1])
        if (k, c) not in cmd:
            raise ConfigError(f"{where}: row {hrow}", f"missing column {name!r} (commands need all 3 cables of every section)")
    if groups["tension"] and set(groups["tension"]) != set(cmd):
        raise ConfigError(f"{where}: row {hrow}", f"tension columns must match the command columns ({arm}/tension_<k>_<c> for every cable)")
    for name in (f"{arm}/{p}" for p in POSE):
        if name not in header:
            raise ConfigError(f"{where}: row {hrow}", f"missing column {name!r}")
    quat_cols = [f"{arm}/{p}" for p in QUAT]
    has_quat = [q in header for q in quat_cols]
    if any(has_quat) and not all(has_quat):
        raise ConfigError(f"{where}: row {hrow}", "give all four quaternion columns tool_qw, tool_qx, tool_qy, tool_qz or none")

    body = [(start + 2 + i, r) for i, r in enumerate(rows[1:]) if any(cell.strip() for cell in r)]
    if len(body) < 2:
        raise ConfigError(where, f"needs at least 2 data rows (got {len(body)})")
    n = len(body)
    numeric = [j for j, h in enumerate(header) if h != "label"]
    values = np.full((n, len(header)), np.nan)
    labels: list[str] = []
    li = header.index("label") if "label" in header else None
    for i, (row_no, r) in enumerate(body):
        if len(r) != len(header):
            raise ConfigError(f"{where}: row {row_no}", f"has {len(r)} cells, the header has {len(header)}")
        for j in numeric:
            cell = r[j].strip()
            if not cell:
                continue
            try:
                v = float(cell)
            except ValueError:
                raise ConfigError(f"{where}: row {row_no}, column {header[j]!r}", f"not a number: {cell!r}") from None
            if not math.isfinite(v):
                raise ConfigError(f"{where}: row {row_no}, column {header[j]!r}", f"must be finite (got {cell!r})")
            values[i, j] = v
        if li is not None:
            labels.append(r[li])
    rownos = [b[0] for b in body]

    def col(name: str) -> Array:
        return values[:, header.index(name)]

    t = col("time")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ConfigError(f"{where}: row {rownos[bad[0]]}, column 'time'", "empty: every row needs a time")
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        i = back[0] + 1
        raise ConfigError(f"{where}: row {rownos[i]}, column 'time'",
                          f"must increase strictly (got {t[i]:g} after {t[i - 1]:g})")
    names = cable_columns(arm, n_sections, kind)
    raw = np.stack([col(nm) for nm in names], axis=1)
    have = np.all(np.isfinite(raw), axis=1)
    partial = np.flatnonzero(np.any(np.isfinite(raw), axis=1) & ~have)
    if partial.size:
        i = partial[0]
        missing = [names[j] for j in range(len(names)) if not np.isfinite(raw[i, j])]
        raise ConfigError(f"{where}: row {rownos[i]}, column {missing[0]!r}", "empty while other commands in the row are set")
    if not have[0]:
        raise ConfigError(f"{where}: row {rownos[0]}, column {names[0]!r}", "the first data row needs the commands")
    if kind == "motor":
        if spool_radius is None:
            raise ConfigError(where, "motor-angle columns need the spool radius (arm.spool_radius)")
        raw = raw * spool_radius
    for j, nm in enumerate(names):
        big = np.flatnonzero(np.abs(raw[:, j]) > 1.0)
        if big.size:
            raise ConfigError(f"{where}: row {rownos[big[0]]}, column {nm!r}",
                              f"cable displacement {raw[big[0], j]:g} m is beyond ±1 m (units are metres)")
    commands = np.stack([np.interp(t, t[have], raw[have, j]) for j in range(raw.shape[1])], axis=1)

    position = np.stack([col(f"{arm}/{p}") for p in POSE], axis=1)
    part = np.flatnonzero(np.any(np.isfinite(position), axis=1) & ~np.all(np.isfinite(position), axis=1))
    if part.size:
        raise ConfigError(f"{where}: row {rownos[part[0]]}", "tool_x, tool_y, tool_z must be all set or all empty")
    if not np.any(np.all(np.isfinite(position), axis=1)):
        raise ConfigError(where, "no row has a measured tool position")
    big = np.flatnonzero(np.any(np.abs(np.nan_to_num(position)) > 10.0, axis=1))
    if big.size:
        raise ConfigError(f"{where}: row {rownos[big[0]]}", "tool position beyond ±10 m (units are metres)")
    quat = None
    if all(has_quat):
        quat = np.stack([col(q) for q in quat_cols], axis=1)
        pos_rows = np.all(np.isfinite(position), axis=1)
        q_rows = np.all(np.isfinite(quat), axis=1)
        mismatch = np.flatnonzero(pos_rows != q_rows)
        if mismatch.size:
            raise ConfigError(f"{where}: row {rownos[mismatch[0]]}", "the quaternion must be set exactly where the position is")
        norms = np.linalg.norm(quat, axis=1)
        off = np.flatnonzero(q_rows & (np.abs(norms - 1.0) > 0.01))
        if off.size:
            raise ConfigError(f"{where}: row {rownos[off[0]]}", f"quaternion norm {norms[off[0]]:.4g} is not 1 (±0.01)")
        quat = quat / norms[:, None]

    def optional(name: str, fill_hold: bool = True) -> Array | None:
        if name not in header:
            return None
        v = col(name)
        ok = np.isfinite(v)
        if not ok[0]:
            raise ConfigError(f"{where}: row {rownos[0]}, column {name!r}", "the first data row needs a value")
        return np.interp(t, t[ok], v[ok]) if fill_hold else v

    tensions = None
    if groups["tension"]:
        tensions = np.stack([col(nm) for nm in cable_columns(arm, n_sections, "tension")], axis=1)
        neg = np.argwhere(tensions < 0)
        if neg.size:
            i, j = neg[0]
            raise ConfigError(f"{where}: row {rownos[i]}, column {cable_columns(arm, n_sections, 'tension')[j]!r}",
                              f"a cable tension cannot be negative (got {tensions[i, j]:g})")
    return Recording(arm, t, commands, position, quat, tensions, optional(f"{arm}/gripper"), optional(f"{arm}/spindle"),
                     labels if li is not None else None, info, kind)


def _fmt(v: float) -> str:
    return "" if not math.isfinite(v) else repr(float(v))


def format_recording(rec: Recording, comments: tuple[str, ...] = ()) -> str:
    """The CSV text of ``rec`` (commands written as cable displacements)."""
    n_sections = rec.n_cables // 3
    info = rec.info
    out = io.StringIO()
    for line in comments:
        out.write(f"# {line}\n")
    out.write(f"# format = {FORMAT}\n# mode = {info.mode}\n# settle_s = {info.settle_s!r}\n"
              f"# gravity = {'true' if info.gravity else 'false'}\n# tool = {info.tool}\n# align = {info.align}\n")
    if info.source:
        out.write(f"# source = {info.source}\n")
    header = ["time", *cable_columns(rec.arm, n_sections)]
    cols: list[Array] = [rec.time, *rec.commands.T]
    if rec.tensions is not None:
        header += cable_columns(rec.arm, n_sections, "tension")
        cols += list(rec.tensions.T)
    header += [f"{rec.arm}/{p}" for p in POSE]
    cols += list(rec.position.T)
    if rec.quaternion is not None:
        header += [f"{rec.arm}/{p}" for p in QUAT]
        cols += list(rec.quaternion.T)
    for name, arr in (("gripper", rec.gripper), ("spindle", rec.spindle)):
        if arr is not None:
            header.append(f"{rec.arm}/{name}")
            cols.append(arr)
    if rec.labels is not None:
        header.append("label")
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(header)
    for i in range(len(rec.time)):
        row = [_fmt(c[i]) for c in cols]
        if rec.labels is not None:
            row.append(rec.labels[i])
        writer.writerow(row)
    return out.getvalue()


def write_recording(rec: Recording, path: str | os.PathLike[str], comments: tuple[str, ...] = ()) -> Path:
    path = Path(path)
    if path.parent and not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, format_recording(rec, comments))
    return path
