"""Run a design study: Optuna asks for designs, the sweep machinery evaluates them, the study resumes.

Storage: the Optuna study (every ask, parameter and tell, the objectives' names) lives in
Optuna's own storage: by default ``<out>/study.journal``, a journal file appended as it
happens; ``storage`` names any other (an RDB URL such as ``sqlite:///studies.db`` or a
PostgreSQL/MySQL server, or another journal file path), ``study_name`` the study in it.
The project keeps ``<out>/evaluations/``, the sweep store of the evaluations (``sweep.json``
the study's identity, which refuses a different study; ``records/<id>.json`` one per finished
evaluation, design x robustness sample, written atomically by the driver; ``log.jsonl`` one
line per evaluation run, the audit trail of "no evaluation twice"): Optuna records trials, not
the evaluations inside one, so this is what lets a killed trial's finished evaluations be
reused and a design proposed twice be evaluated once. The report files sit at the top.

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

import hashlib
import json
import math
import os
import re
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..configio import ConfigError
from ..sweep.runner import preflight
from ..sweep.spec import Variant, variant_id
from ..sweep.store import FORMAT_VERSION, ResultStore, write_provenance
from .design import Params, StudySweep, check_config, check_designs, design_params, evaluation_variant, robustness_samples, study_sweep
from .spec import SUCCESS, OptimizeSpec

Backend = Literal["local", "ray"]
STUDY_NAME = "optimize"  # the study's name in the default journal (--study-name: another)
JOURNAL = "study.journal"
IDENTITY_ATTR = "continuum_sim.identity"  # study user attribute: hash of the spec the study was made for
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


def storage_label(storage: str | None) -> str:
    """``storage`` as it may be shown and recorded: an RDB URL's password masked; None is the folder's journal."""
    if storage is None:
        return JOURNAL
    return re.sub(r"(://[^:/@]+):[^@]*@", r"\1:***@", storage)


def open_storage(root: Path, storage: str | None) -> Any:
    """Optuna's storage for the study: ``<root>/study.journal`` by default; an RDB URL (``scheme://...``); else a journal file path."""
    from optuna.storages import JournalStorage, RDBStorage
    from optuna.storages.journal import JournalFileBackend

    if storage is None:
        return JournalStorage(JournalFileBackend(str(root / JOURNAL)))
    try:
        if "://" in storage:
            return RDBStorage(storage)
        return JournalStorage(JournalFileBackend(storage))
    except Exception as exc:  # noqa: BLE001 - a bad URL, a missing database driver, an unreachable server: one line
        text = " ".join(str(exc).split())[:200]
        raise ConfigError("--storage", f"cannot open {storage_label(storage)}: {type(exc).__name__}: {text}") from None


def spec_hash(spec: OptimizeSpec) -> str:
    """Hash of what the Optuna study must belong to: the spec's identity without the trial budget (--trials may grow it)."""
    identity = spec.identity()
    identity["optimizer"] = {k: v for k, v in identity["optimizer"].items() if k != "trials"}
    return hashlib.sha256(json.dumps(identity, sort_keys=True, default=str).encode()).hexdigest()[:16]


def open_study(spec: OptimizeSpec, root: Path, storage: str | None = None, study_name: str | None = None) -> Any:
    """The study's Optuna study (created or loaded) with its objectives' names set (``trials_dataframe``, optuna-dashboard).

    ``storage``: None for ``<root>/study.journal``; ``study_name``: default ``optimize`` in the
    folder's journal, the folder's name in another storage. A study of that name made for
    another spec is refused (``ConfigError`` on ``--study-name``).
    """
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    name = study_name or (STUDY_NAME if storage is None else root.resolve().name)
    study = optuna.create_study(storage=open_storage(root, storage), study_name=name, directions=list(spec.directions),  # type: ignore[arg-type]  # checked: minimize | maximize
                                load_if_exists=True, sampler=make_sampler(spec, 0))
    mine = spec_hash(spec)
    theirs = study.user_attrs.get(IDENTITY_ATTR)
    if theirs is not None and theirs != mine:
        raise ConfigError("--study-name", f"study {name!r} in {storage_label(storage)} belongs to another spec; choose another --study-name")
    if [d.name.lower() for d in study.directions] != list(spec.directions):
        raise ConfigError("--study-name", f"study {name!r} in {storage_label(storage)} has other objectives; choose another --study-name")
    if theirs is None:
        study.set_user_attr(IDENTITY_ATTR, mine)
    labels = [o.label for o in spec.objectives]
    if study.metric_names != labels:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            study.set_metric_names(labels)
    return study


def _follow_budget(root: Path, sweep: StudySweep) -> None:
    """Let ``--trials`` grow or shrink a study's budget: a folder whose identity differs from ``sweep``'s
    only in ``optimizer.trials`` takes the new identity (any other difference is refused by the store)."""
    marker = root / EVALUATIONS / "sweep.json"
    if not marker.exists():
        return
    try:
        stored = json.loads(marker.read_text())
    except (OSError, json.JSONDecodeError):
        return  # the store names the problem
    identity = {"format": FORMAT_VERSION, **sweep.identity()}
    old = stored.get("identity")
    if not isinstance(old, dict) or old == identity:
        return
    try:
        comparable = json.loads(json.dumps(old))
        comparable["grid"]["optimizer"]["trials"] = identity["grid"]["optimizer"]["trials"]
    except (KeyError, TypeError):
        return
    if comparable == json.loads(json.dumps(identity, default=str)):
        from ..configio import atomic_write_text

        atomic_write_text(marker, json.dumps({**stored, "identity": identity}, indent=1, sort_keys=True))


def run_study(
    spec: OptimizeSpec,
    out: str | os.PathLike[str],
    *,
    workers: int | None = None,
    backend: Backend = "local",
    address: str | None = None,
    progress: bool = True,
    spec_path: str | os.PathLike[str] | None = None,
    storage: str | None = None,
    study_name: str | None = None,
) -> StudyResult:
    """Run (or resume) the study of ``spec`` in folder ``out`` until its trial budget is told; then write the report.

    ``spec_path``: the spec file, hashed into ``provenance.json`` (written at the start and at the end).
    ``storage``, ``study_name``: where Optuna keeps the study (``open_study``); the evaluations'
    records stay in ``out`` whatever the storage. One driver per study: the folder's lock keeps a
    second one out (distributing a study is the evaluations' business: ``backend = "ray"``).
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
    with pools.open_pool(backend, workers, address) as pool, store.lock():
        if address is not None and isinstance(pool, pools.RayPool):
            pool.session.connect()  # a refused connection (authentication, version) is one line before the folder is touched
        _follow_budget(root, sweep)
        store.prepare(sweep)
        write_provenance(root, "optimize", spec, spec_path)
        records = store.load()
        study = open_study(spec, root, storage, study_name)
        running = optuna.trial.TrialState.RUNNING
        n_resumed = sum(1 for t in study.get_trials(deepcopy=False) if t.state == running)
        told = sum(1 for t in study.get_trials(deepcopy=False) if t.state.is_finished())
        bar = tqdm(total=budget, initial=told, desc=f"optimize ({spec.optimizer.sampler})", unit="design", disable=not progress,
                   dynamic_ncols=True)
        counts = {"run": 0, "reused": 0}
        try:
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
        best = sorted(study.best_trials, key=lambda t: t.number)  # Optuna's Pareto front (feasible trials when constrained)
        summary = write_report(spec, trials, records, root, best=best,
                               study={"name": study.study_name, "storage": storage_label(storage), "spec_sha256": spec_hash(spec),
                                      "worker_startup_s": getattr(pool, "worker_startup_s", None)})
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


def evaluate_design(spec: OptimizeSpec, config: Any, samples: list[Params]) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Evaluate one design as its study did: each robustness sample's evaluation, then ``aggregate``.

    ``config``: the design's scenario (a best design's TOML: the study's base with the design's
    values set); ``samples``: the robustness samples' values (``[()]`` without robustness).
    The same path as the study's pool (``sweep.backends.payload`` into
    ``sweep.worker.evaluate_payload``, in this process), each result kept as the store keeps
    it (non-finite metrics null), so the objective values equal the recorded ones exactly.
    """
    from ..sweep import backends
    from ..sweep.worker import evaluate_payload

    sweep = StudySweep(config, (), spec.evaluation, ())
    records = []
    for k, sample in enumerate(samples):
        variant = Variant(k, sample, variant_id(sample, spec.evaluation))
        result = evaluate_payload(backends.payload(sweep, variant, None))
        metrics = {key: None if isinstance(v, float) and not math.isfinite(v) else v for key, v in (result.get("metrics") or {}).items()}
        records.append({"variant_id": variant.variant_id, "params": dict(sample), "status": result["status"], "error": result.get("error"),
                        "metrics": metrics, "cpu_s": result.get("cpu_s")})
    return records, aggregate(spec, records)
