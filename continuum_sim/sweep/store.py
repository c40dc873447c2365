"""A sweep's results folder: its spec, one JSON record per finished variant.

Layout::

    <out>/spec.toml         the spec as given (for people)
    <out>/sweep.json        the resolved spec (base config, grid values, evaluation)
    <out>/records/<id>.json one per finished variant, written atomically
    <out>/results.csv       rebuilt from the records in grid order (+ .parquet)
    <out>/plots/            each metric against each swept parameter
    <out>/provenance.json   code, configuration and spec hashes, libraries, machine (``write_provenance``)

A record is written (temp file + ``os.replace``) only once its variant has finished, so
a killed sweep leaves whole records or none, and resuming skips exactly the variants
whose record exists. The folder refuses a different sweep (changed base, grid or
evaluation), so resumed records always belong to the spec being run.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..configio import ConfigError, atomic_write_text
from .spec import SweepSpec, Variant

FORMAT_VERSION = 1


def write_provenance(root: str | os.PathLike[str], command: str, spec: Any, spec_path: str | os.PathLike[str] | None) -> None:
    """``root/provenance.json`` of a study (sweep, sensitivity, optimisation): written at its start and again at its end.

    ``spec``: any spec with a ``base`` ScenarioConfig and its ``source_text``; ``spec_path``: the spec
    file (its bytes are hashed); without one, the hash is that of the spec text the study was read from.
    """
    from .. import provenance
    from ..params.registry import registry_sha256

    doc = provenance.collect(provenance.current_command(command), config_toml=provenance.config_toml(spec.base),
                             registry_sha256=registry_sha256(), spec_path=None if spec_path is None else Path(spec_path))
    source = getattr(spec, "source_text", "")
    if spec_path is None and source:
        doc["hashes"]["spec"] = provenance.sha256_text(source)
    provenance.write(Path(root), doc)


def _finite(value: Any) -> Any:
    """JSON has no NaN/inf: a non-finite metric is recorded as null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class ResultStore:
    """Read and write one sweep folder."""

    def __init__(self, root: str | os.PathLike[str]) -> None:
        self.root = Path(root)
        self.records_dir = self.root / "records"

    def prepare(self, spec: SweepSpec) -> None:
        """Create the folder for ``spec``, or check an existing one holds the same sweep."""
        identity = {"format": FORMAT_VERSION, **spec.identity()}
        marker = self.root / "sweep.json"
        if marker.exists():
            try:
                stored = json.loads(marker.read_text())
            except (OSError, json.JSONDecodeError) as exc:
                raise ConfigError("--out", f"{self.root}/sweep.json is unreadable ({exc}); use another --out") from None
            if stored.get("identity") != identity:
                changed = [k for k in ("base", "grid", "evaluation") if stored.get("identity", {}).get(k) != identity[k]]
                what = ", ".join(changed) or "format"
                raise ConfigError(
                    "--out",
                    f"{self.root} holds a different sweep ({what} changed); use another --out or delete that folder",
                )
        else:
            if self.root.exists() and any(self._foreign(p) for p in self.root.iterdir()):
                raise ConfigError("--out", f"{self.root} exists and is not a sweep folder; use another --out")
            # The marker first: once it exists, a killed start is simply resumed.
            atomic_write_text(marker, json.dumps({"identity": identity, "base_path": spec.base_path}, indent=1, sort_keys=True))
            if spec.source_text:
                atomic_write_text(self.root / "spec.toml", spec.source_text)
        self.records_dir.mkdir(parents=True, exist_ok=True)
        for stale in self.records_dir.glob(".*.tmp"):  # a write interrupted by a kill
            stale.unlink(missing_ok=True)

    def _foreign(self, path: Path) -> bool:
        """Not left by an interrupted start of a sweep (hidden temp files, empty records/)."""
        if path.name.startswith("."):
            return False
        return not (path == self.records_dir and path.is_dir() and not any(path.iterdir()))

    @contextlib.contextmanager
    def lock(self) -> Iterator[None]:
        """Hold the folder for one sweep process; the OS releases it even on SIGKILL."""
        if self.root.exists() and not (self.root / "sweep.json").exists() and any(self._foreign(p) for p in self.root.iterdir()):
            raise ConfigError("--out", f"{self.root} exists and is not a sweep folder; use another --out")
        self.root.mkdir(parents=True, exist_ok=True)
        with open(self.root / ".lock", "a+") as fh:
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise ConfigError("--out", f"{self.root} is in use by another running sweep") from None
            try:
                yield
            finally:
                fcntl.flock(fh, fcntl.LOCK_UN)

    def path(self, variant_id: str) -> Path:
        return self.records_dir / f"{variant_id}.json"

    def load(self) -> dict[str, dict[str, Any]]:
        """Every readable record, by variant id (an unreadable one is treated as missing)."""
        out = {}
        for path in sorted(self.records_dir.glob("*.json")):
            try:
                record = json.loads(path.read_text())
            except (OSError, json.JSONDecodeError):
                continue
            if isinstance(record, dict) and record.get("variant_id") == path.stem:
                out[path.stem] = record
        return out

    def write(self, variant: Variant, spec: SweepSpec, result: dict[str, Any], backend: str) -> dict[str, Any]:
        """Record one finished variant atomically; returns the record."""
        record = {
            "variant_id": variant.variant_id,
            "index": variant.index,
            "params": variant.param_dict,
            "evaluation": spec.evaluation.to_dict(),
            "status": result["status"],
            "error": result.get("error"),
            "metrics": {k: _finite(v) for k, v in (result.get("metrics") or {}).items()},
            "wall_s": result.get("wall_s"),
            "cpu_s": result.get("cpu_s"),
            "host": result.get("host"),
            "pid": result.get("pid"),
            "backend": backend,
            "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        }
        atomic_write_text(self.path(variant.variant_id), json.dumps(record, indent=1, sort_keys=True, allow_nan=False))
        return record
