"""Run a sensitivity study on the sweep machinery: its records store, its worker and its backends.

The samples become sweep ``Variant``s (id = hash of the parameter values and the
evaluation), evaluated by ``sweep.backends`` (local worker processes or Ray) through
``sweep.worker.evaluate_payload`` and recorded one JSON file each by
``sweep.store.ResultStore``: a killed study resumes without re-evaluating a finished
sample, and the folder refuses a different study. The report (``report.py``) is rebuilt
from the records after every run.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from ..configio import ConfigError, set_path, to_dict
from ..sweep import backends
from ..sweep.runner import preflight
from ..sweep.spec import SweepSpec, Variant, variant_id
from ..sweep.store import ResultStore, write_provenance
from .design import sample_matrix, sample_params
from .spec import SensitivitySpec

Backend = Literal["local", "ray"]


@dataclass(frozen=True)
class StudySweep(SweepSpec):
    """The study as the sweep store and backends see it: its samples as the variants, its design as the identity."""

    design: dict[str, Any] = field(default_factory=dict)
    samples: tuple[Variant, ...] = ()

    def variants(self, progress: bool = False) -> list[Variant]:  # noqa: ARG002 - the samples are already built
        return list(self.samples)

    def identity(self) -> dict[str, Any]:
        return {"base": to_dict(self.base), "grid": self.design, "evaluation": self.evaluation.to_dict()}


@dataclass(frozen=True)
class StudyResult:
    root: Path
    n_rows: int  # rows of the sample matrix
    n_distinct: int  # distinct configurations evaluated (rows may repeat a point)
    n_skipped: int  # already recorded before this run
    n_run: int
    n_failed: int
    summary: dict[str, Any]
    worker_startup_s: float | None = None  # Ray: starting the warm workers (not part of any variant's cost)


def study_sweep(spec: SensitivitySpec) -> tuple[StudySweep, list[str]]:
    """The study's ``StudySweep`` (distinct samples) and each matrix row's variant id."""
    matrix = sample_matrix(spec)
    row_ids: list[str] = []
    distinct: dict[str, Variant] = {}
    for params in sample_params(spec, matrix):
        vid = variant_id(params, spec.evaluation)
        row_ids.append(vid)
        if vid not in distinct:
            distinct[vid] = Variant(len(distinct), params, vid)
    sweep = StudySweep(spec.base, (), spec.evaluation, spec.metrics, spec.base_path, spec.source_text,
                       design=spec.design(), samples=tuple(distinct.values()))
    return sweep, row_ids


def check_samples(sweep: StudySweep, limit: int | None = None) -> None:
    """Every sample's configuration must validate and suit the evaluation: before any work, naming the first that does not."""
    import copy

    from ..configio import from_dict
    from ..limits import check_model_geometry, check_scenario

    base = to_dict(sweep.base)
    for variant in sweep.samples[:limit]:
        try:
            data = copy.deepcopy(base)  # all of a sample's values set in one rebuild (apply_params rebuilds per value)
            for path, value in variant.params:
                set_path(data, path, value)
            config = from_dict(type(sweep.base), data)
            if sweep.evaluation.static:
                check_model_geometry(config)
            else:
                check_scenario(config)
            sweep.evaluation.check(config)
        except ConfigError as exc:
            label = ", ".join(f"{p} = {v:g}" for p, v in variant.params)
            raise ConfigError(exc.field, f"{exc.message} (sample {variant.index}: {label}); narrow [ranges]") from None


def run_study(
    spec: SensitivitySpec,
    out: str | os.PathLike[str],
    *,
    workers: int | None = None,
    backend: Backend = "local",
    address: str | None = None,
    progress: bool = True,
    spec_path: str | os.PathLike[str] | None = None,
) -> StudyResult:
    """Evaluate every sample of ``spec`` not yet recorded under ``out``, then analyse and report; resumable.

    ``spec_path``: the spec file, hashed into ``provenance.json`` (written at the start and at the end).
    """
    from tqdm import tqdm

    from .report import write_report

    if address is not None and backend != "ray":
        raise ConfigError("--address", "only applies to --backend ray")
    preflight(backend, workers)
    sweep, row_ids = study_sweep(spec)
    check_samples(sweep)
    store = ResultStore(out)
    with backends.study_session(backend, workers, address) as session, store.lock():  # Ray: connected before the folder is touched
        store.prepare(sweep)
        write_provenance(store.root, "sensitivity", spec, spec_path)
        wanted = {v.variant_id for v in sweep.samples}
        records = {k: r for k, r in store.load().items() if k in wanted}
        pending = [v for v in sweep.samples if v.variant_id not in records]
        n_skipped = len(sweep.samples) - len(pending)
        bar = tqdm(total=len(sweep.samples), initial=n_skipped, desc=f"sensitivity ({spec.method})", unit="run",
                   disable=not progress, dynamic_ncols=True)
        failed_now = 0
        startup_s = None

        def on_result(variant: Variant, result: dict[str, Any]) -> None:
            nonlocal failed_now
            records[variant.variant_id] = store.write(variant, sweep, result, backend)
            failed_now += result["status"] != "ok"
            bar.update(1)
            if failed_now:
                bar.set_postfix(failed=failed_now)

        try:
            if pending:
                if session is not None:
                    session.run(sweep, pending, None, on_result)
                    startup_s = session.worker_startup_s
                else:
                    backends.run_processes(sweep, pending, workers or backends.default_workers(), None, on_result)
        finally:
            bar.close()
        summary = write_report(spec, row_ids, records, store.root)
        write_provenance(store.root, "sensitivity", spec, spec_path)
    n_failed = sum(1 for r in records.values() if r["status"] != "ok")
    return StudyResult(store.root, len(row_ids), len(sweep.samples), n_skipped, len(pending), n_failed, summary, startup_s)
