"""Which kind of folder this is, its page, and ``report.html`` written into it."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

from ..configio import ConfigError, atomic_write_text
from .design_studies import optimize_page, sensitivity_page, study_kind
from .run import run_page, write_poster
from .studies import generic_page, identify_page, sweep_page, validation_page

REPORT_NAME = "report.html"

PAGES: dict[str, Callable[[Path], str]] = {
    "run": run_page,
    "sweep": sweep_page,
    "validation": validation_page,
    "identification": identify_page,
    "sensitivity": sensitivity_page,
    "optimize": optimize_page,
    "study": generic_page,
}


def detect_kind(folder: Path) -> str:
    """``run``, ``sensitivity``, ``optimize``, ``sweep``, ``validation``, ``identification`` or ``study`` (any other folder with a summary or plots).

    Recognised by the files each command writes: a run its ``config.toml`` with
    ``metrics.json``/``trajectory.npz``; a sensitivity study its ``summary.json`` naming the
    method (Morris or Sobol'), an optimisation its ``summary.json`` with the objectives and the
    sampler (both checked before ``sweep.json``, which a sensitivity folder also holds, as its
    sample store); a sweep ``sweep.json``; an identification
    ``identified.toml`` beside ``report.json``; a validation ``report.json`` holding ``rows``.
    A folder with none of these but a JSON or CSV summary or PNGs is a ``study`` (so is
    ``continuum-sim replay``'s folder, recognised by its ``replay.json``).
    Raises ``ConfigError`` for a folder with nothing to show.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError("DIR", f"{folder} is not a folder")
    replay = (folder / "replay.json").is_file()  # `continuum-sim replay`'s folder: config and trajectory too, but a study
    if (folder / "config.toml").is_file() and not replay and any((folder / n).is_file() for n in ("metrics.json", "trajectory.npz", "RUNNING")):
        return "run"
    design = study_kind(folder)
    if design is not None:
        return design
    if (folder / "sweep.json").is_file():
        return "sweep"
    if (folder / "identified.toml").is_file() and (folder / "report.json").is_file():
        return "identification"
    if (folder / "report.json").is_file():
        try:
            if "rows" in json.loads((folder / "report.json").read_text()):
                return "validation"
        except (OSError, ValueError, TypeError):
            pass
    if any(folder.glob("*.json")) or any(folder.glob("*.csv")) or any(folder.glob("*.png")) or any(folder.glob("plots/*.png")):
        return "study"
    raise ConfigError("DIR", f"{folder} holds no run, sweep, validation, identification or study results "
                             "(no metrics.json, sweep.json, report.json, CSV, JSON or PNG)")


def report_page(folder: Path, kind: str | None = None) -> str:
    """The HTML page of ``folder`` (its kind detected unless given)."""
    return PAGES[kind or detect_kind(folder)](Path(folder))


def write_report(folder: Path, kind: str | None = None) -> Path:
    """Write ``folder/report.html`` atomically (a run's video poster first); returns its path."""
    kind = kind or detect_kind(folder)
    if kind == "run":
        write_poster(Path(folder))
    path = Path(folder) / REPORT_NAME
    atomic_write_text(path, report_page(folder, kind))
    return path
