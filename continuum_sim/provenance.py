"""``provenance.json``: what produced a run or study folder (code, configuration, libraries, machine).

Every folder the package writes (a run, a sweep, a sensitivity or optimisation study, a
validation report, an identification) holds one, written when the folder is started (so a
killed study still says what it was) and, for studies, rewritten at the end. Schema 1::

    {"schema": 1, "command": "run", "argv": ["continuum-sim", "run", ...], "created_utc": "2026-12-07T14:00:00Z",
     "package": {"name": "continuum_sim", "version": "0.1.0"},
     "git": {"commit": "<40 hex>" | null, "dirty": bool | null, "changed": ["continuum_sim/x.py", ...]},
     "code_sha256": "<hex>",
     "hashes": {"config": "<hex>" | null, "registry": "<hex>" | null, "spec": "<hex>" | null},
     "versions": {"python": ..., "mujoco": ..., "numba": ..., "numpy": ..., "scipy": ..., "SALib": ..., "optuna": ...,
                  "dm_control": ...},
     "machine": {"platform": ..., "cpu": ..., "cpu_count": int | null,
                 "threads": {"NUMBA_NUM_THREADS": ..., "OMP_NUM_THREADS": ..., "numba_cpu_name": ...}}}

* ``git``: the checkout the package source lives in (``git rev-parse HEAD``; ``dirty`` and
  ``changed`` from ``git status --porcelain -- continuum_sim pyproject.toml``, so a run's own
  output files never make it dirty); all null / empty where the package is not in a git
  checkout or git is missing or slow. Git never fails a run.
* ``code_sha256``: sha256 over the package's ``.py`` files and ``data/*.toml`` (sorted by
  relative path; each path, its size and its bytes), so an installed wheel has one too.
* ``hashes.config``: sha256 of the resolved configuration's TOML text (``config.toml``);
  ``registry``: of the parameter registry's metadata (passed in by the caller,
  ``continuum_sim.params.registry.registry_sha256``); ``spec``: of the study spec file's bytes.
* ``machine.threads``: the environment variables as set (an integer where they parse as one), null when unset.

The git and code hashes are computed once per process (a sweep of many runs pays them once).
Low layer: imports only ``configio`` and the standard library.
"""

from __future__ import annotations

import datetime
import functools
import hashlib
import json
import os
import platform
import subprocess
import sys
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

from .configio import atomic_write_text, dumps_toml, to_dict

SCHEMA = 1
FILENAME = "provenance.json"
PACKAGE_NAME = "continuum_sim"
PACKAGE_ROOT = Path(__file__).resolve().parent  # the package source (tests point it at a copy)
# Distributions whose versions are recorded (importlib.metadata names; a missing one is null).
LIBRARIES = ("mujoco", "numba", "numpy", "scipy", "SALib", "optuna", "dm_control")
GIT_TIMEOUT_S = 5.0
MAX_CHANGED = 20

_invocation: dict[str, Any] = {"argv": None, "command": None}


def set_invocation(argv: Sequence[str] | None, command: str | None = None) -> None:
    """Record the command line of this process's CLI call (``continuum_sim.cli`` does; None forgets it)."""
    _invocation["argv"] = None if argv is None else [str(a) for a in argv]
    _invocation["command"] = command


def current_command(default: str) -> str:
    """The CLI subcommand being run, or ``default`` outside a CLI call (a script, a test)."""
    command = _invocation["command"]
    return command if isinstance(command, str) and command else default


def _argv() -> list[str]:
    if _invocation["argv"] is not None:
        return list(_invocation["argv"])
    return [Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "python", *sys.argv[1:]]


# ------------------------------------------------------------------------ hashes
def sha256_text(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def config_toml(config: Any) -> str:
    """The TOML text of a resolved configuration, as ``config.toml`` holds it (``configio.save_toml``)."""
    return dumps_toml(to_dict(config))


def _code_files(root: Path) -> list[Path]:
    files = [p for p in root.rglob("*.py") if "__pycache__" not in p.relative_to(root).parts]
    files += list((root / "data").glob("*.toml"))
    return sorted(set(files), key=lambda p: p.relative_to(root).as_posix())


@functools.lru_cache(maxsize=8)
def _code_sha256(root: str) -> str:
    base = Path(root)
    digest = hashlib.sha256()
    for path in _code_files(base):
        data = path.read_bytes()
        digest.update(path.relative_to(base).as_posix().encode("utf-8") + b"\0" + str(len(data)).encode() + b"\0")
        digest.update(data)
    return digest.hexdigest()


def code_sha256(root: Path | None = None) -> str:
    """sha256 over the package's ``.py`` files and ``data/*.toml`` (cached per process and root)."""
    return _code_sha256(str(PACKAGE_ROOT if root is None else root))


def file_sha256(path: Path) -> str | None:
    """sha256 of a file's bytes; None where it cannot be read."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


# ------------------------------------------------------------------------ git
def _git(root: Path, *args: str) -> str | None:
    """stdout of ``git -C root ARGS``, or None on any failure (no git, not a checkout, timeout)."""
    try:
        done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=GIT_TIMEOUT_S,
                              stdin=subprocess.DEVNULL, check=False)
    except (OSError, subprocess.SubprocessError, ValueError):
        return None
    return done.stdout if done.returncode == 0 else None


@functools.lru_cache(maxsize=8)
def _git_state(package_root: str) -> tuple[str | None, bool | None, tuple[str, ...]]:
    package = Path(package_root)
    root = package.parent
    name = package.name
    tracked = _git(root, "ls-files", "--", f"{name}/__init__.py")
    if not tracked or not tracked.strip():  # not a checkout, or the package is not part of it (a venv inside a repo)
        return None, None, ()
    head = (_git(root, "rev-parse", "HEAD") or "").strip()
    commit = head if len(head) == 40 and all(c in "0123456789abcdef" for c in head) else None
    status = _git(root, "status", "--porcelain", "--untracked-files=all", "--", name, "pyproject.toml")
    if status is None:
        return commit, None, ()
    changed = [line[3:].split(" -> ")[-1].strip().strip('"') for line in status.splitlines() if len(line) > 3]
    return commit, bool(changed), tuple(changed[:MAX_CHANGED])


def git_state(package_root: Path | None = None) -> dict[str, Any]:
    """``{"commit", "dirty", "changed"}`` of the checkout holding the package source (cached per process)."""
    commit, dirty, changed = _git_state(str(PACKAGE_ROOT if package_root is None else package_root))
    return {"commit": commit, "dirty": dirty, "changed": list(changed)}


def clear_caches() -> None:
    """Forget the cached git state and code hash (after the source changed in this process)."""
    _code_sha256.cache_clear()
    _git_state.cache_clear()


# ------------------------------------------------------------------------ environment
def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None
    except Exception:  # noqa: BLE001 - a broken installation's metadata never fails a run
        return None


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                key, sep, value = line.partition(":")
                if sep and key.strip() in ("model name", "Hardware", "cpu model"):
                    return value.strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _env_number(name: str) -> int | str | None:
    value = os.environ.get(name)
    if value is None:
        return None
    try:
        return int(value)
    except ValueError:
        return value


def _machine() -> dict[str, Any]:
    return {
        "platform": platform.platform(),
        "cpu": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "threads": {
            "NUMBA_NUM_THREADS": _env_number("NUMBA_NUM_THREADS"),
            "OMP_NUM_THREADS": _env_number("OMP_NUM_THREADS"),
            "numba_cpu_name": os.environ.get("NUMBA_CPU_NAME") or None,
        },
    }


# ------------------------------------------------------------------------ the document
def collect(command: str, *, config_toml: str | None, registry_sha256: str | None, spec_path: Path | None) -> dict[str, Any]:
    """The provenance document of a folder ``command`` is writing (see the module docstring for the schema)."""
    return {
        "schema": SCHEMA,
        "command": command,
        "argv": _argv(),
        "created_utc": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "package": {"name": PACKAGE_NAME, "version": _version(PACKAGE_NAME)},
        "git": git_state(),
        "code_sha256": code_sha256(),
        "hashes": {
            "config": None if config_toml is None else sha256_text(config_toml),
            "registry": registry_sha256,
            "spec": None if spec_path is None else file_sha256(Path(spec_path)),
        },
        "versions": {"python": platform.python_version(), **{name: _version(name) for name in LIBRARIES}},
        "machine": _machine(),
    }


def write(folder: Path, doc: dict[str, Any]) -> None:
    """``folder/provenance.json``, atomically."""
    atomic_write_text(Path(folder) / FILENAME, json.dumps(doc, indent=1, ensure_ascii=False) + "\n")


def record(folder: Path, command: str, *, config_toml: str | None = None, registry_sha256: str | None = None,
           spec_path: Path | None = None) -> dict[str, Any]:
    """``collect`` then ``write``; returns the document."""
    doc = collect(command, config_toml=config_toml, registry_sha256=registry_sha256, spec_path=spec_path)
    write(folder, doc)
    return doc
