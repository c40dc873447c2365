"""The ``import-recording`` and ``import-robot`` subcommands (registered by ``sysid.cli``).

Bad input raises ``ConfigError`` (one line, exit 2 at the CLI's error boundary); nothing
is written before the input has been read and checked.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from ..configio import ConfigError, atomic_write_text


def _triple(text: str | None, option: str) -> tuple[float, float, float]:
    if text is None:
        return (0.0, 0.0, 0.0)
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ConfigError(option, f"must be X,Y,Z in metres (got {text!r})") from None
    if len(values) != 3 or not all(math.isfinite(v) and abs(v) <= 1.0 for v in values):
        raise ConfigError(option, f"must be three finite numbers X,Y,Z within +-1 m (got {text!r})")
    return values[0], values[1], values[2]


def cmd_import_recording(args: argparse.Namespace) -> int:
    from .opencr import import_folder

    offset = _triple(args.marker_offset, "--marker-offset")
    if not (math.isfinite(args.settling_time) and 0.0 < args.settling_time <= 10.0):
        raise ConfigError("--settling-time", f"must satisfy 0 < S <= 10 s (got {args.settling_time})")
    sections = None
    robot_text = None
    if args.robot is not None:
        from .robot import import_robot

        robot_text, robot = import_robot(args.robot)
        sections = len(robot["arm"]["sections"])
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ConfigError("--out", f"{args.out} exists and is not a folder")
    written, notes, angles = import_folder(args.data, out, args.settling_time, offset, sections=sections)
    for note in notes:
        print(f"import-recording: {note}")
    for kind, path in written.items():
        print(f"wrote {path} ({kind})")
    if robot_text is not None:
        if any(offset):
            robot_text += f"\n[arm.tools]\nmarker_offset = [{offset[0]!r}, {offset[1]!r}, {offset[2]!r}]  # --marker-offset\n"
        atomic_write_text(out / "robot.toml", robot_text)
        print(f"wrote {out / 'robot.toml'} (from {args.robot})")
    print("tendon angles from the pulls (deg, base->tip): "
          + "; ".join(", ".join(f"{a:.1f}" for a in row) for row in angles))
    return 0


def cmd_import_robot(args: argparse.Namespace) -> int:
    from .robot import import_robot

    text, _ = import_robot(args.robot)
    out = Path(args.out) if args.out else Path(args.robot).with_suffix(".toml")
    if out.is_dir():
        raise ConfigError("--out", f"{out} is a folder; give a file name (ROBOT.toml)")
    atomic_write_text(out, text)
    print(text.split("\n\n", 1)[0])
    print(f"wrote {out}")
    return 0


def add_import_commands(sub: Any) -> None:
    ir = sub.add_parser("import-recording", help="OpenCR-style session CSVs (any robot) to recordings (docs/sysid.md)")
    ir.add_argument("data", metavar="DIR", help="the session folder (CSV files with timestamp, pattern_label, servo_<id>_mm, tip_x/y/z)")
    ir.add_argument("--out", default="runs/recordings", help="folder for <kind>.recording.csv (default: runs/recordings)")
    ir.add_argument("--settling-time", type=float, default=0.3, help="settle per command in the quasi-static replay, s (default 0.3)")
    ir.add_argument("--marker-offset", metavar="X,Y,Z", help="marker position in the tip frame, m (default 0,0,0)")
    ir.add_argument("--robot", metavar="ROBOT.json", help="the robot's OpenCR generation JSON: checked and written as robot.toml")
    ir.set_defaults(func=cmd_import_recording)
    rb = sub.add_parser("import-robot", help="an OpenCR generation JSON to a scenario TOML (docs/sysid.md)")
    rb.add_argument("robot", metavar="ROBOT.json")
    rb.add_argument("--out", help="the TOML to write (default: ROBOT.toml beside the JSON)")
    rb.set_defaults(func=cmd_import_robot)
