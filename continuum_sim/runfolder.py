"""Run folders that tell the truth: refused when occupied, marked while running, marked at the end.

A run folder is in one of these states (docs/errors.md):

* ``running``: the ``RUNNING`` marker exists (it names the process); a folder whose
  marker names a dead process was killed (SIGKILL, power loss) and is ``incomplete``;
* ``complete`` / ``interrupted`` (Ctrl-C, SIGTERM) / ``diverged`` / ``failed`` (any other
  error after the run started, e.g. a full disk): ``metrics.json`` has that ``status``
  (and ``status_reason``) and there is no marker.

A new run refuses a folder that already holds files unless ``--overwrite``, which
clears it first, and only if it looks like a run folder (never a home directory).
A run that did not complete has its partial video renamed ``video.<status>.mp4`` (an
interrupted run's render workers are stopped and its video discarded), so no
``video.mp4`` ever holds part of a run.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path
from typing import Any

from .configio import ConfigError, atomic_write_text, shorten
from .lifetime import pid_alive

MARKER = "RUNNING"
STATES = ("running", "complete", "interrupted", "diverged", "failed", "incomplete")
# What a run writes; a folder holding anything else is not cleared by --overwrite.
RUN_FILES = {
    MARKER, "config.toml", "parameters.json", "metrics.json", "trajectory.npz", "video.mp4", "video.interrupted.mp4",
    "video.diverged.mp4", "video.failed.mp4", "plots", "model", "MUJOCO_LOG.TXT", "report.html", "replay.rrd", "poster.png",
    "provenance.json",
}


def _is_run_entry(path: Path) -> bool:
    return path.name in RUN_FILES or path.name.startswith(".")  # hidden: temp files of atomic writes, partial video


def prepare_run_folder(out: Path, overwrite: bool, option: str = "--out") -> None:
    """Refuse an occupied folder unless ``overwrite``; with it, clear a run folder first."""
    if not out.exists():
        return
    entries = list(out.iterdir())
    if not entries:
        return
    if not overwrite:
        state = read_state(out)
        raise ConfigError(
            option,
            f"{shorten(str(out))} already holds a run ({state}); pass --overwrite to replace it or choose another --out",
        )
    foreign = [p.name for p in entries if not _is_run_entry(p)]
    if foreign:
        raise ConfigError(
            option,
            f"{shorten(str(out))} is not a run folder (it holds {shorten(foreign[0], 40)}); --overwrite only clears run folders",
        )
    if (out / MARKER).exists() and read_state(out) == "running":
        raise ConfigError(option, f"{shorten(str(out))} is in use by a running run (see {MARKER}); wait or choose another --out")
    for path in entries:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()


def mark_running(out: Path, command: str = "run") -> None:
    """Write the ``RUNNING`` marker (first thing in the folder)."""
    out.mkdir(parents=True, exist_ok=True)
    info = {"status": "running", "pid": os.getpid(), "command": command, "started_unix": time.time()}
    atomic_write_text(out / MARKER, json.dumps(info, indent=1) + "\n")


def read_state(out: Path) -> str:
    """One of ``STATES`` (or ``unknown`` for a folder no run wrote)."""
    marker = out / MARKER
    if marker.exists():
        try:
            pid = int(json.loads(marker.read_text()).get("pid", -1))
        except (OSError, ValueError, AttributeError):
            return "incomplete"
        return "running" if pid > 0 and pid != os.getpid() and pid_alive(pid) else "incomplete"
    try:
        metrics = json.loads((out / "metrics.json").read_text())
        status = metrics.get("status")
    except (OSError, ValueError, AttributeError):
        return "unknown"
    if status in STATES:
        return status
    return "diverged" if metrics.get("diverged") else "complete"  # written by run_scenario outside the CLI


def finish(out: Path, status: str, reason: str | None = None) -> None:
    """Record the final ``status`` in metrics.json (creating it if the run stopped before writing it), drop the marker.

    Any status but ``complete`` renames a partial ``video.mp4`` to ``video.<status>.mp4``.
    """
    if status not in ("complete", "interrupted", "diverged", "failed"):
        raise ValueError(f"status: must be complete, interrupted, diverged or failed (got {status!r})")
    if not out.is_dir():
        return
    if status != "complete":
        video = out / "video.mp4"
        if video.exists():
            os.replace(video, out / f"video.{status}.mp4")
    path = out / "metrics.json"
    metrics: dict[str, Any] = {}
    if path.exists():
        try:
            loaded = json.loads(path.read_text())
            metrics = loaded if isinstance(loaded, dict) else {}
        except (OSError, ValueError):
            metrics = {}
    if metrics.get("status") != status or (reason and metrics.get("status_reason") != reason):
        metrics["status"] = status
        if reason:
            metrics["status_reason"] = reason
        atomic_write_text(path, json.dumps(metrics, indent=2, sort_keys=True))
    (out / MARKER).unlink(missing_ok=True)


def discard_if_empty(out: Path) -> bool:
    """Remove the marker (and the folder, if then empty) of a run refused before writing; True if done."""
    if not out.is_dir() or any(p.name != MARKER and not p.name.startswith(".") for p in out.iterdir()):
        return False
    (out / MARKER).unlink(missing_ok=True)
    try:
        out.rmdir()
    except OSError:
        pass
    return True
