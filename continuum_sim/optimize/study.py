"""Run a design study: Optuna asks for designs, the sweep machinery evaluates them, the study resumes.

Storage: ``<out>/study.journal``, an Optuna journal file (every ask, parameter and tell
appended as it happens), and ``<out>/evaluations/``, the sweep store of the evaluations
(``sweep.json`` the study's identity, which refuses a different study; ``records/<id>.json``
one per finished evaluation, written atomically by the driver; ``log.jsonl`` one line per
evaluation run, the audit trail of "no evaluation twice"). The report files sit at the top.

Generations: the study asks ``optimizer.batch`` designs at a time, evaluates them all (each
design × each robustness sample is one evaluation on the pool), tells Optuna each design's
objectives and constraints once its evaluations are in, then asks the next generation. The
sampler is re-made for every trial and seeded from (seed, trial number): what it proposes
depends only on the told history, never on which worker finished first, so the same seed
gives the same trials for any worker count, and a resumed study proposes what an
uninterrupted one would have.

Kill and resume: a trial asked but not told before the kill (RUNNING in the journal) is
re-run exactly once on resume, with the parameters it was given; of its evaluations, those
recorded before the kill are reused (never evaluated again) and only those that were in
flight or not started run. A trial that was told is never touched again.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..configio import ConfigError
from ..sweep.runner import preflight
from ..sweep.spec import Variant
from ..sweep.store import ResultStore, write_provenance
from .design import Params, StudySweep, check_config, check_designs, design_params, evaluation_variant, robustness_samples, study_sweep
from .spec import SUCCESS, OptimizeSpec

Backend = Literal["local", "ray"]
STUDY_NAME = "optimize"
JOURNAL = "study.journal"
EVALUATIONS = "evaluations"  # the sweep store's folder inside the study folder
AUDIT = "log.jsonl"  # in it


@dataclass(frozen=True)
class StudyResult:
    root: Path
    n_trials: int
    n_resumed: int  # trials asked before this run and re-run now (killed before they were told)
    n_evaluated: int  # evaluations run by this call
    n_reused: int  # evaluations this call took from records
    n_failed: int  # failed trials in the whole study
    summary: dict[str, Any]


def trial_seed(seed: int, number: int) -> int:
    return int(np.random.SeedSequence([seed, number]).generate_state(1)[0] & 0x7FFFFFFF)


def make_sampler(spec: OptimizeSpec, number: int) -> Any:
    """The sampler for trial ``number``: the spec's kind, seeded from (seed, number)."""
    import optuna

    opt, seed = spec.optimizer, trial_seed(spec.optimizer.seed, number)
    # Constraints reach NSGA-II and TPE as each trial's ``set_constraint`` values (``_tell``), read from the storage.
    if opt.sampler == "nsga2":
        return optuna.samplers.NSGAIISampler(population_size=opt.batch, seed=seed)
    if opt.sampler == "tpe":
        return optuna.samplers.TPESampler(seed=seed, multivariate=True, n_startup_trials=max(opt.batch, 8))
    if opt.sampler == "cmaes":
        return optuna.samplers.CmaEsSampler(seed=seed, popsize=opt.batch if opt.batch >= 2 else None)
    if opt.sampler == "grid":
        # the study's seed, not the trial's: Optuna's grid sampler shuffles the grid by its seed once and gives trial n
        # the n-th point, so every trial must see the same shuffle (a per-trial seed repeats points)
        return _grid_sampler()({v.path: v.grid_values() for v in spec.variables}, seed=opt.seed)
    return optuna.samplers.RandomSampler(seed=seed)


def _grid_sampler() -> type:
    import optuna

    class Grid(optuna.samplers.GridSampler):
        """Optuna's grid sampler without its ``study.stop()`` once the grid is covered (only allowed inside
        ``study.optimize``; here the trial budget, at most the grid's size, ends the study)."""

        def after_trial(self, study: Any, trial: Any, state: Any, values: Any) -> None:
            pass

    return Grid


def suggest(spec: OptimizeSpec, trial: Any) -> dict[str, Any]:
    """The trial's design (values it already holds are returned as stored)."""
    out: dict[str, Any] = {}
    for v in spec.variables:
        if v.integer:
            out[v.path] = trial.suggest_int(v.path, int(v.low), int(v.high), log=v.log)
        else:
            out[v.path] = trial.suggest_float(v.path, v.low, v.high, log=v.log)
    return out


def _quantile(values: list[float], q: float) -> float:
    return float(np.quantile(np.asarray(values, dtype=float), q))


def aggregate(spec: OptimizeSpec, records: list[dict[str, Any]]) -> dict[str, Any]:
    """A design's outcome from its evaluations' records: objective values (or its failure) and constraints."""
    ok = [r for r in records if r["status"] == "ok"]
    success = [all(c.holds(r["metrics"]) for c in spec.constraints) for r in ok] + [False] * (len(records) - len(ok))
    p_success = sum(success) / len(records)
    failures = sorted({r["error"] for r in records if r["status"] != "ok"})
    out: dict[str, Any] = {SUCCESS: p_success, "failures": failures, "n_failed_evaluations": len(records) - len(ok)}
    if not spec.robust:
        if not ok:
            return {**out, "values": None, "failure": failures[0] if failures else "evaluation failed"}
        metrics = ok[0]["metrics"]
        out["constraints"] = [c.violation(metrics) for c in spec.constraints] or [0.0]
    else:
        min_success = spec.robustness.min_success
        out["constraints"] = [0.0 if min_success is None else min_success - p_success]
    values: list[float] = []
    for objective in spec.objectives:
        if objective.metric == SUCCESS:
            values.append(p_success)
            continue
        samples = [r["metrics"].get(objective.metric) for r in ok]
        finite = [float(v) for v in samples if isinstance(v, (int, float)) and math.isfinite(v)]
        if not finite:
            reason = failures[0] if failures else f"metric {objective.metric} missing or not finite in every evaluation"
            return {**out, "values": None, "failure": reason}
        values.append(float(np.mean(finite)) if objective.aggregate == "mean" else _quantile(finite, objective.q))
    return {**out, "values": values, "failure": None}


def constrained(spec: OptimizeSpec) -> bool:
    """Whether the sampler sees constraints: per evaluation without robustness, the success probability's with it."""
    return bool(spec.constraints) and (not spec.robust or spec.robustness.min_success is not None)


def _tell(spec: OptimizeSpec, study: Any, trial_id: int, number: int, outcome: dict[str, Any], variant_ids: list[str]) -> None:
    import optuna

    handle = optuna.trial.Trial(study, trial_id)
    handle.set_user_attr("variant_ids", variant_ids)
    handle.set_user_attr(SUCCESS, outcome[SUCCESS])
    handle.set_user_attr("failures", outcome["failures"])
    handle.set_user_attr("n_failed_evaluations", outcome["n_failed_evaluations"])
    if outcome["values"] is None:
        handle.set_user_attr("failure", outcome["failure"])
        study.tell(number, state=optuna.trial.TrialState.FAIL)
    else:
        handle.set_user_attr("constraints", outcome["constraints"])  # the report's feasibility
        if constrained(spec):
            names = ["min_success"] if spec.robust else [f"{i}:{c.metric}" for i, c in enumerate(spec.constraints)]
            for name, value in zip(names, outcome["constraints"]):
                handle.set_constraint(name, value)  # feasible when <= 0; NSGA-II and TPE rank infeasible designs last
        study.tell(number, outcome["values"])


def open_study(spec: OptimizeSpec, root: Path) -> Any:
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    storage = JournalStorage(JournalFileBackend(str(root / JOURNAL)))
    return optuna.create_study(storage=storage, study_name=STUDY_NAME, directions=list(spec.directions),  # type: ignore[arg-type]  # checked: minimize | maximize
                               load_if_exists=True,
                               sampler=make_sampler(spec, 0))


def run_study(
    spec: OptimizeSpec,
    out: str | os.PathLike[str],
    *,
    workers: int | None = None,
    backend: Backend = "local",
    address: str | None = None,
    progress: bool = True,
    spec_path: str | os.PathLike[str] | None = None,
) -> StudyResult:
    """Run (or resume) the study of ``spec`` in folder ``out`` until its trial budget is told; then write the report.

    ``spec_path``: the spec file, hashed into ``provenance.json`` (written at the start and at the end).
    """
    import optuna
    from tqdm import tqdm

    from . import pool as pools
    from .report import write_report

    if address is not None and backend != "ray":
        raise ConfigError("--address", "only applies to --backend ray")
    preflight(backend, workers)
    check_designs(spec)
    if backend == "ray" and address is not None:
        from ..sweep import backends

        backends.probe_address(address)
    sweep = study_sweep(spec)
    samples = robustness_samples(spec)
    root = Path(out)
    if root.exists() and not (root / EVALUATIONS / "sweep.json").exists() and any(not p.name.startswith(".") and p.name != EVALUATIONS for p in root.iterdir()):
        raise ConfigError("--out", f"{root} exists and is not a study folder; use another --out")
    store = ResultStore(root / EVALUATIONS)
    budget = spec.optimizer.trials
    with store.lock():
        store.prepare(sweep)
        write_provenance(root, "optimize", spec, spec_path)
        records = store.load()
        study = open_study(spec, root)
        running = optuna.trial.TrialState.RUNNING
        n_resumed = sum(1 for t in study.get_trials(deepcopy=False) if t.state == running)
        told = sum(1 for t in study.get_trials(deepcopy=False) if t.state.is_finished())
        bar = tqdm(total=budget, initial=told, desc=f"optimize ({spec.optimizer.sampler})", unit="design", disable=not progress,
                   dynamic_ncols=True)
        counts = {"run": 0, "reused": 0}
        try:
            with pools.open_pool(backend, workers, address) as pool:
                while True:
                    trials = study.get_trials(deepcopy=False)
                    open_trials = [t for t in trials if t.state == running]
                    if not open_trials:
                        if len(trials) >= budget:
                            break
                        n = len(trials)
                        for number in range(n, min(budget, n + spec.optimizer.batch - n % spec.optimizer.batch)):
                            study.sampler = make_sampler(spec, number)
                            suggest(spec, study.ask())
                        continue
                    _generation(spec, study, open_trials, samples, sweep, store, records, pool, backend, counts, bar)
        finally:
            bar.close()
        trials = study.get_trials(deepcopy=False)
        summary = write_report(spec, trials, records, root)
        write_provenance(root, "optimize", spec, spec_path)
    n_failed = sum(1 for t in trials if t.state == optuna.trial.TrialState.FAIL)
    return StudyResult(root, len(trials), n_resumed, counts["run"], counts["reused"], n_failed, summary)


def _generation(spec: OptimizeSpec, study: Any, open_trials: list[Any], samples: list[Params], sweep: StudySweep,
                store: ResultStore, records: dict[str, dict[str, Any]], pool: Any, backend: str, counts: dict[str, int],
                bar: Any) -> None:
    """Evaluate the open trials' designs (what is not recorded yet), telling each trial once all of its evaluations are in."""
    import optuna

    plans: dict[int, tuple[Any, list[str]]] = {}  # trial number -> (trial, its evaluations' variant ids)
    todo: dict[str, Variant] = {}
    audit: dict[str, tuple[int, int]] = {}
    for t in open_trials:
        study.sampler = make_sampler(spec, t.number)
        handle = optuna.trial.Trial(study, t._trial_id)
        design = design_params(spec, suggest(spec, handle))
        ids: list[str] = []
        invalid = None
        try:
            check_config(spec, design)
        except ConfigError as exc:  # the design space is continuous: a corner check cannot see every design
            invalid = f"invalid design: {exc.field}: {exc.message}"
        for k, sample in enumerate(samples):
            variant = evaluation_variant(spec, design, sample, t.number * len(samples) + k)
            ids.append(variant.variant_id)
            if variant.variant_id in records:
                counts["reused"] += 1
            elif invalid is not None:
                records[variant.variant_id] = store.write(variant, sweep, {"status": "failed", "metrics": {}, "error": invalid}, backend)
            elif variant.variant_id not in todo:
                todo[variant.variant_id] = variant
                audit[variant.variant_id] = (t.number, k)
        plans[t.number] = (t, ids)

    def settle() -> None:
        for number in sorted(plans):
            trial, ids = plans[number]
            if all(i in records for i in ids):
                _tell(spec, study, trial._trial_id, number, aggregate(spec, [records[i] for i in ids]), ids)
                del plans[number]
                bar.update(1)

    def on_result(variant: Variant, result: dict[str, Any]) -> None:
        records[variant.variant_id] = store.write(variant, sweep, result, backend)
        number, k = audit[variant.variant_id]
        line = {"variant_id": variant.variant_id, "trial": number, "sample": k, "status": result["status"],
                "pid": result.get("pid"), "cpu_s": result.get("cpu_s"), "finished_at": time.time()}
        with open(store.root / AUDIT, "a") as fh:
            fh.write(json.dumps(line) + "\n")
        counts["run"] += 1
        settle()

    settle()  # trials whose evaluations were all recorded before a kill
    if todo:
        pool.run(sweep, list(todo.values()), on_result)
    settle()
    if plans:  # pragma: no cover - every evaluation returns a result (failures included)
        raise RuntimeError(f"trials {sorted(plans)} still lack evaluations after their generation")
