"""A design study's report, rebuilt from the Optuna study and the records after every run.

Layout (beside the Optuna ``study.journal`` and the evaluations' store ``evaluations/``)::

    <out>/trials.csv        one row per trial: design, objectives, success probability, constraints, failure
    <out>/pareto.csv        the feasible non-dominated designs (Optuna's ``study.best_trials``)
    <out>/trials.parquet, pareto.parquet  the same tables, when pyarrow is installed
    <out>/best/trial_<n>.toml  each of them as a scenario TOML (continuum-sim run --config), headed by
                            what reproduces its objectives (``design.header_lines``: continuum-sim evaluate)
    <out>/summary.json      counts, the spec's objectives and the best designs, for people and the report renderer
    <out>/plots/pareto.png  objectives of every trial, the front drawn (one objective: value per trial, best so far)
    <out>/plots/history.png each objective and the success probability against the trial number
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any

from ..configio import atomic_write_bytes, atomic_write_text, dumps_toml, from_dict, to_dict
from .design import config_dict, design_params, header_lines, robustness_samples
from .spec import SUCCESS, OptimizeSpec

PARQUET_MISSING = "pyarrow is not installed: trials.parquet and pareto.parquet were not written (pip install pyarrow)"


def dominates(a: list[float], b: list[float], directions: list[str]) -> bool:
    """``a`` is no worse than ``b`` in every objective and better in one."""
    sign = [1.0 if d == "minimize" else -1.0 for d in directions]
    no_worse = all(s * x <= s * y for s, x, y in zip(sign, a, b))
    return no_worse and any(s * x < s * y for s, x, y in zip(sign, a, b))


def pareto_indices(points: list[list[float]], directions: list[str]) -> list[int]:
    """Indices of the non-dominated points (duplicates all kept), for tables without an Optuna study (``compare``).

    It agrees with Optuna's ``study.best_trials`` on a study's feasible completed trials
    (tests/test_optimize.py checks it), which is what the report uses.
    """
    return [i for i, p in enumerate(points) if not any(dominates(q, p, directions) for j, q in enumerate(points) if j != i)]


def feasible(trial: Any) -> bool:
    return all(c <= 0.0 for c in trial.user_attrs.get("constraints", [0.0]))


def _csv(rows: list[dict[str, Any]], columns: list[str]) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, columns, lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def _row(spec: OptimizeSpec, trial: Any, records: dict[str, dict[str, Any]]) -> dict[str, Any]:
    ids = trial.user_attrs.get("variant_ids", [])
    cpu = [records[i].get("cpu_s") for i in ids if i in records]
    row: dict[str, Any] = {"trial": trial.number, "state": trial.state.name, "feasible": int(trial.state.name == "COMPLETE" and feasible(trial))}
    row.update({v.path: trial.params.get(v.path) for v in spec.variables})
    for objective, value in zip(spec.objectives, trial.values or [None] * len(spec.objectives)):
        row[objective.label] = value
    row[SUCCESS] = trial.user_attrs.get(SUCCESS)
    row["constraint_violation"] = sum(max(0.0, c) for c in trial.user_attrs.get("constraints", [0.0]))
    row["evaluations"] = len(ids)
    row["failed_evaluations"] = trial.user_attrs.get("n_failed_evaluations")
    row["failure"] = trial.user_attrs.get("failure") or "; ".join(trial.user_attrs.get("failures", []))
    row["cpu_s"] = sum(c for c in cpu if c is not None)
    return row


def write_parquet(rows: list[dict[str, Any]], columns: list[str], path: Path) -> bool:
    """``rows`` as a Parquet table beside the CSV (numbers as float64, text as strings); False when pyarrow is missing."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return False
    data = {}
    for c in columns:
        values = [row.get(c) for row in rows]
        if any(isinstance(v, str) for v in values):
            data[c] = pa.array([None if v is None else str(v) for v in values], type=pa.string())
        else:
            data[c] = pa.array([None if v is None else float(v) for v in values], type=pa.float64())
    sink = pa.BufferOutputStream()
    pq.write_table(pa.table(data), sink)
    atomic_write_bytes(path, sink.getvalue().to_pybytes())
    return True


def _provenance(root: Path) -> dict[str, Any]:
    try:
        doc = json.loads((root / "provenance.json").read_text())
    except (OSError, json.JSONDecodeError):
        return {}
    return doc if isinstance(doc, dict) else {}


def write_report(spec: OptimizeSpec, trials: list[Any], records: dict[str, dict[str, Any]], root: Path, *,
                 best: list[Any], study: dict[str, Any] | None = None) -> dict[str, Any]:
    """Write trials.csv/.parquet, pareto.csv/.parquet, best/*.toml, summary.json and plots/; returns the summary.

    ``best``: the study's ``best_trials`` (Optuna's Pareto front; only feasible trials when the
    study is constrained); ``study``: its name, storage and spec hash, for the summary and the
    best designs' headers.
    """
    study = study or {}
    rows = [_row(spec, t, records) for t in trials]
    columns = ["trial", "state", "feasible", *[v.path for v in spec.variables], *[o.label for o in spec.objectives]]
    columns += [c for c in (SUCCESS, "constraint_violation", "evaluations", "failed_evaluations", "failure", "cpu_s") if c not in columns]
    atomic_write_text(root / "trials.csv", _csv(rows, columns))
    best_rows = [r for r in rows if r["trial"] in {t.number for t in best}]
    atomic_write_text(root / "pareto.csv", _csv(best_rows, columns))
    parquet = write_parquet(rows, columns, root / "trials.parquet") and write_parquet(best_rows, columns, root / "pareto.parquet")
    best_dir = root / "best"
    best_dir.mkdir(exist_ok=True)
    for stale in best_dir.glob("trial_*.toml"):
        stale.unlink()
    configs = {}
    provenance = _provenance(root)
    samples = robustness_samples(spec) if spec.robust else []
    for t in best:
        path = best_dir / f"trial_{t.number}.toml"
        config = from_dict(type(spec.base), config_dict(spec, design_params(spec, t.params)))
        header = header_lines(spec, trial=t.number, values=list(t.values), success=t.user_attrs.get(SUCCESS), samples=samples,
                              folder=str(root), study=study, provenance=provenance)
        atomic_write_text(path, "".join(f"# {line}\n" for line in header) + "\n" + dumps_toml(to_dict(config)))
        configs[t.number] = str(path.relative_to(root))
    states = {s: sum(1 for t in trials if t.state.name == s) for s in ("COMPLETE", "FAIL", "RUNNING")}
    failures: dict[str, int] = {}
    for t in trials:
        for reason in t.user_attrs.get("failures", []):
            key = reason.split(":")[0] if ":" in reason else reason
            failures[key] = failures.get(key, 0) + 1
    cpu = [float(r["cpu_s"]) for r in records.values() if r.get("cpu_s") is not None]
    summary = {
        "kind": "optimize",
        "sampler": spec.optimizer.sampler,
        "seed": spec.optimizer.seed,
        "trials": len(trials),
        "budget": spec.optimizer.trials,
        "states": states,
        "feasible": sum(r["feasible"] for r in rows),
        "evaluations": len(records),
        "samples_per_design": spec.n_samples,
        "cpu_s": sum(cpu),
        "variables": [{"path": v.path, "low": v.low, "high": v.high, "log": v.log, "int": v.integer} for v in spec.variables],
        "objectives": [{"label": o.label, "metric": o.metric, "direction": o.direction, "aggregate": o.aggregate} for o in spec.objectives],
        "constraints": [{"metric": c.metric, "min": c.low, "max": c.high} for c in spec.constraints],
        "robustness": {"samples": spec.robustness.samples, "parameters": [p.path for p in spec.robustness.parameters],
                       "min_success": spec.robustness.min_success},
        "failures": failures,
        "best": [{"trial": t.number, "params": dict(t.params), "values": dict(zip([o.label for o in spec.objectives], t.values)),
                  SUCCESS: t.user_attrs.get(SUCCESS), "config": configs[t.number]} for t in best],
        "files": {"trials": "trials.csv", "pareto": "pareto.csv", "plots": ["plots/pareto.png", "plots/history.png"],
                  **({"trials_parquet": "trials.parquet", "pareto_parquet": "pareto.parquet"} if parquet else {})},
        "notes": [] if parquet else [PARQUET_MISSING],
        "optuna": {"study_name": study.get("name"), "storage": study.get("storage"), "spec_sha256": study.get("spec_sha256")},
        "worker_startup_s": study.get("worker_startup_s"),  # Ray's warm workers starting, apart from every evaluation's cost
    }
    atomic_write_text(root / "summary.json", json.dumps(summary, indent=1, sort_keys=True, allow_nan=False, default=_plain))
    _plots(spec, trials, best, root / "plots")
    return summary


def _plain(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return str(value)


def _plots(spec: OptimizeSpec, trials: list[Any], best: list[Any], folder: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")  # files only: never a window, never GL
    import matplotlib.pyplot as plt

    folder.mkdir(exist_ok=True)
    done = [t for t in trials if t.state.name == "COMPLETE"]
    ok = [t for t in done if feasible(t)]
    bad = [t for t in done if not feasible(t)]
    failed = [t for t in trials if t.state.name == "FAIL"]
    labels = [o.label for o in spec.objectives]
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    if len(labels) >= 2:
        for group, colour, marker, name in ((ok, "tab:blue", "o", "feasible"), (bad, "tab:gray", "x", "infeasible")):
            ax.scatter([t.values[0] for t in group], [t.values[1] for t in group], s=24, c=colour, marker=marker, label=f"{name} ({len(group)})")
        order = sorted(best, key=lambda t: t.values[0])
        ax.plot([t.values[0] for t in order], [t.values[1] for t in order], "-o", c="tab:red", ms=7, mfc="none", label=f"Pareto front ({len(best)})")
        ax.set_xlabel(f"{labels[0]} ({spec.objectives[0].direction})")
        ax.set_ylabel(f"{labels[1]} ({spec.objectives[1].direction})")
    else:
        ax.scatter([t.number for t in ok], [t.values[0] for t in ok], s=24, c="tab:blue", label=f"feasible ({len(ok)})")
        ax.scatter([t.number for t in bad], [t.values[0] for t in bad], s=24, c="tab:gray", marker="x", label=f"infeasible ({len(bad)})")
        sign = 1.0 if spec.objectives[0].direction == "minimize" else -1.0
        xs, ys, best_value = [], [], math.inf
        for t in sorted(ok, key=lambda t: t.number):
            best_value = min(best_value, sign * t.values[0])
            xs.append(t.number)
            ys.append(sign * best_value)
        ax.step(xs, ys, where="post", c="tab:red", label="best feasible so far")
        ax.set_xlabel("trial")
        ax.set_ylabel(f"{labels[0]} ({spec.objectives[0].direction})")
    ax.set_title(f"{spec.optimizer.sampler}: {len(trials)} designs, {len(failed)} failed")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(folder / "pareto.png", dpi=110)
    plt.close(fig)

    series = labels + ([SUCCESS] if spec.robust and SUCCESS not in labels else [])
    fig, axes = plt.subplots(len(series), 1, figsize=(6.4, 2.2 * len(series) + 0.6), sharex=True, squeeze=False)
    for ax, name in zip(axes[:, 0], series):
        if name in labels:
            i = labels.index(name)
            ax.scatter([t.number for t in done], [t.values[i] for t in done], s=14, c=["tab:blue" if feasible(t) else "tab:gray" for t in done])
        else:
            ax.scatter([t.number for t in done], [t.user_attrs.get(SUCCESS) for t in done], s=14, c="tab:green")
        for t in failed:
            ax.axvline(t.number, c="tab:red", lw=0.5, alpha=0.5)
        ax.set_ylabel(name, fontsize=8)
    axes[-1, 0].set_xlabel("trial (red lines: failed designs)")
    fig.tight_layout()
    fig.savefig(folder / "history.png", dpi=110)
    plt.close(fig)
