"""Run a sweep: check, skip what is recorded, evaluate the rest, rebuild table and plots."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from ..configio import ConfigError
from . import backends
from .report import write_plots, write_table
from .spec import SweepSpec, Variant
from .store import ResultStore, write_provenance

Backend = Literal["local", "ray"]
Batch = Literal["auto", "on", "off"]


@dataclass(frozen=True)
class SweepResult:
    """What a run of ``run_sweep`` did and where its outputs are."""

    root: Path
    n_variants: int
    n_skipped: int  # already recorded before this run
    n_run: int
    n_failed: int  # failed variants in the whole table
    mode: str
    tables: tuple[Path, ...]
    plots: tuple[Path, ...]
    records: dict[str, dict[str, Any]]
    worker_startup_s: float | None = None  # Ray: starting the warm workers (not part of any variant's cost)


def choose_mode(spec: SweepSpec, backend: Backend, batch: Batch) -> str:
    """``shared`` (one compiled model, rollout threads) or ``process`` (one task per variant).

    ``auto`` picks ``shared`` for static evaluations on the local backend: it gives
    bit-identical metrics and skips the per-variant model build (see benchmarks/sweep.py).
    """
    if batch == "off" or backend == "ray":
        if batch == "on":
            raise ConfigError("--batch", "on is only available with --backend local")
        return "process"
    if not spec.evaluation.static:
        if batch == "on":
            raise ConfigError("--batch", f"on needs a static evaluation (gravity_sag, tip_deflection), not {spec.evaluation.kind}")
        return "process"
    return "shared"


def preflight(backend: Backend, workers: int | None) -> None:
    """Checks that need the installation, not the spec; still before any work."""
    if workers is not None and not 1 <= workers <= 4096:
        raise ConfigError("--workers", f"must satisfy 1 <= workers <= 4096 (got {workers})")
    if backend not in ("local", "ray"):
        raise ConfigError("--backend", f"must be 'local' or 'ray' (got {backend!r})")


def run_sweep(
    spec: SweepSpec,
    out: str | os.PathLike[str],
    *,
    workers: int | None = None,
    backend: Backend = "local",
    address: str | None = None,
    batch: Batch = "auto",
    retry_failed: bool = False,
    progress: bool = True,
    spec_path: str | os.PathLike[str] | None = None,
) -> SweepResult:
    """Evaluate every variant of ``spec`` not yet recorded under ``out``; resumable.

    ``spec_path``: the spec file, hashed into ``provenance.json`` (written at the start and at the end).
    """
    from tqdm import tqdm

    if address is not None and backend != "ray":
        raise ConfigError("--address", "only applies to --backend ray")
    preflight(backend, workers)
    mode = choose_mode(spec, backend, batch)
    store = ResultStore(out)
    with backends.study_session(backend, workers, address) as session, store.lock():  # Ray: connected before the folder is touched
        store.prepare(spec)
        write_provenance(store.root, "sweep", spec, spec_path)
        records = store.load()
        variants = spec.variants(progress=progress)
        wanted = {v.variant_id for v in variants}
        records = {k: r for k, r in records.items() if k in wanted}
        pending = [
            v
            for v in variants
            if v.variant_id not in records or (retry_failed and records[v.variant_id]["status"] != "ok")
        ]
        n_skipped = len(variants) - len(pending)
        run_root = str(store.root / "runs") if getattr(spec.evaluation, "keep_runs", False) else None

        startup_s = None
        bar = tqdm(total=len(variants), initial=n_skipped, desc="sweep", unit="variant", disable=not progress, dynamic_ncols=True)
        failed_now = 0

        def on_result(variant: Variant, result: dict[str, Any]) -> None:
            nonlocal failed_now
            records[variant.variant_id] = store.write(variant, spec, result, f"{backend}/{mode}")
            failed_now += result["status"] != "ok"
            bar.update(1)
            if failed_now:
                bar.set_postfix(failed=failed_now)

        try:
            if pending:
                n_workers = workers or backends.default_workers()
                if session is not None:
                    session.run(spec, pending, run_root, on_result)
                    startup_s = session.worker_startup_s
                elif mode == "shared":
                    backends.run_shared(spec, pending, n_workers, on_result, progress=progress)
                else:
                    backends.run_processes(spec, pending, n_workers, run_root, on_result)
        finally:
            bar.close()
        tables = write_table(spec, records, store.root)
        plots = write_plots(spec, records, store.root)
        write_provenance(store.root, "sweep", spec, spec_path)
    n_failed = sum(1 for r in records.values() if r["status"] != "ok")
    return SweepResult(store.root, len(variants), n_skipped, len(pending), n_failed, mode, tuple(tables), tuple(plots), records, startup_s)
