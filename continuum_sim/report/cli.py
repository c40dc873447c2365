"""The ``report`` and ``export`` subcommands (registered by ``continuum_sim.cli``; docs/report.md)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..configio import ConfigError


def cmd_report(args: argparse.Namespace) -> int:
    from .pages import detect_kind, write_report

    folder = Path(args.dir)
    kind = detect_kind(folder)  # a folder with nothing to show: one line, exit 2
    path = write_report(folder, kind)
    print(f"wrote {path} ({kind} report, {path.stat().st_size / 1e3:.0f} kB)")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    if not args.rerun:
        raise ConfigError("export", "choose a format: --rerun (a Rerun recording, .rrd)")
    from .rerun_export import export_rerun, require_rerun

    require_rerun()  # before any reading: a missing extra is one line, exit 2
    run_dir = Path(args.run_dir)
    out = Path(args.out) if args.out else run_dir / "replay.rrd"
    if out.exists() and out.is_dir():
        raise ConfigError("--out", f"{out} is a folder; give a file name (NAME.rrd)")
    summary = export_rerun(run_dir, out)
    print(f"wrote {summary['path']} ({summary['bytes'] / 1e6:.1f} MB, {summary['frames']} frames, "
          f"{len(summary['entities'])} entities, {summary['kerf_columns']} kerf columns"
          f"{' shown as they were cut' if summary['kerf_timed'] else ''}); view it: rerun {summary['path']}")
    return 0


def add_commands(sub: Any) -> None:
    """Register ``report`` and ``export`` on the main parser's subparsers."""
    rp = sub.add_parser("report", help="write DIR/report.html: one page for a run, sweep, validation, identification or study folder")
    rp.add_argument("dir", metavar="DIR", help="a run folder or a study results folder")
    rp.set_defaults(func=cmd_report)

    ex = sub.add_parser("export", help="export a run folder for interactive replay (--rerun: a Rerun .rrd recording)")
    ex.add_argument("run_dir", metavar="RUN_DIR", help="a run folder written by `continuum-sim run`")
    ex.add_argument("--rerun", action="store_true", help="write a Rerun recording (needs the extra: pip install -e '.[replay]')")
    ex.add_argument("--out", help="the .rrd file to write (default: RUN_DIR/replay.rrd)")
    ex.set_defaults(func=cmd_export)
