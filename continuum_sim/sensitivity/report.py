"""A study folder's report, rebuilt from its records: tables, summary and plots.

Files (besides the sweep store's ``sweep.json``, ``spec.toml`` and ``records/``):

* ``samples.csv``: one row per sample-matrix row: parameter values, status, metrics;
  ``samples.parquet`` the same, when pyarrow is installed (else a note in summary.json);
* ``indices.csv``: one row per (metric, parameter): μ, μ*, σ, μ* 95 % half-width (Morris)
  or S1, S_T and their half-widths (Sobol');
* ``summary.json``: method, counts, per-metric indices, the parameters ranked by strength, and
  ``warnings``: where the sample is too small for its intervals (``design.sample_size_warnings``);
* ``summary.md``: the indices with their 95 % intervals as a table, the warnings above it;
* ``plots/indices.png``: μ* with σ per metric (Morris; S1 and S_T for Sobol'), strongest on top;
* ``plots/outcome_map.png``: every metric over the two strongest parameters, the samples
  that did not complete the task marked.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..configio import atomic_write_bytes, atomic_write_figure, atomic_write_text
from . import uncertainty
from .design import analyze_morris, analyze_sobol, outputs, sample_matrix, sample_size_warnings, strength
from .spec import OUTCOME_METRIC, SensitivitySpec

PARQUET_MISSING = "pyarrow is not installed: samples.parquet was not written (pip install pyarrow)"


def _cell(value: Any) -> str:
    if value is None:
        return ""
    return repr(value) if isinstance(value, float) else str(value)


def _csv(header: list[str], rows: list[list[Any]]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows([[_cell(v) for v in row] for row in rows])
    return buffer.getvalue()


def write_parquet(header: list[str], rows: list[list[Any]], path: Path) -> bool:
    """The table as Parquet beside its CSV (numbers as float64, text as strings); False when pyarrow is missing."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return False
    data = {}
    for c, name in enumerate(header):
        values = [row[c] for row in rows]
        if any(isinstance(v, str) for v in values):
            data[name] = pa.array([None if v is None else str(v) for v in values], type=pa.string())
        else:
            data[name] = pa.array([None if v is None else float(v) for v in values], type=pa.float64())
    sink = pa.BufferOutputStream()
    pq.write_table(pa.table(data), sink)
    atomic_write_bytes(path, sink.getvalue().to_pybytes())
    return True


def write_report(spec: SensitivitySpec, row_ids: list[str], records: dict[str, dict[str, Any]], root: Path) -> dict[str, Any]:
    """Analyse what is recorded and write the report files; returns the summary."""
    matrix = sample_matrix(spec)
    rows = [records.get(vid) for vid in row_ids]
    values = np.array([[f.value(u) for f, u in zip(spec.factors, row)] for row in matrix])

    header = ["row", "variant_id", *spec.paths, "status", "error", *spec.metrics, "cpu_s"]
    table = []
    for i, (vid, record) in enumerate(zip(row_ids, rows)):
        metrics = (record or {}).get("metrics") or {}
        status = "pending" if record is None else record["status"]
        table.append([i, vid, *values[i].tolist(), status, (record or {}).get("error") or "",
                      *[metrics.get(m) for m in spec.metrics], (record or {}).get("cpu_s")])
    atomic_write_text(root / "samples.csv", _csv(header, table))
    parquet = write_parquet(header, table, root / "samples.parquet")

    analyses: dict[str, dict[str, Any]] = {}
    if spec.method == "uncertainty":
        analyses["uncertainty"] = uncertainty.analyze(spec, values, rows)
        ranking = uncertainty.strength(spec, analyses["uncertainty"])
        halves = analyses["uncertainty"]["success_by_half_range"]
        index_rows = [["success", p, halves[p]["lower"]["success"], halves[p]["upper"]["success"], ranking[p]] for p in spec.paths]
        atomic_write_text(root / "indices.csv", _csv(["metric", "parameter", "success_lower_half", "success_upper_half", "difference"],
                                                     index_rows))
    for metric in spec.metrics if spec.method != "uncertainty" else ():
        y = outputs(rows, metric)
        analysis = analyze_morris(spec, matrix, y) if spec.method == "morris" else analyze_sobol(spec, y)
        finite = y[np.isfinite(y)]
        analysis["range"] = [float(finite.min()), float(finite.max())] if finite.size else None
        analyses[metric] = analysis
    if spec.method != "uncertainty":
        keys = ["mu", "mu_star", "sigma", "mu_star_conf"] if spec.method == "morris" else ["S1", "S1_conf", "ST", "ST_conf"]
        index_rows = [
            [metric, path, *[a["indices"][path][k] for k in keys]]
            for metric, a in analyses.items() if a.get("indices") for path in spec.paths
        ]
        atomic_write_text(root / "indices.csv", _csv(["metric", "parameter", *keys], index_rows))
        ranking = strength(spec, analyses)
    ranked = sorted(spec.paths, key=lambda p: -ranking[p])
    done = [r for r in rows if r is not None]
    distinct = {vid: records[vid] for vid in set(row_ids) if vid in records}
    completed = outputs(rows, OUTCOME_METRIC) if OUTCOME_METRIC in spec.metrics else None
    summary: dict[str, Any] = {
        "kind": "sensitivity",
        "method": spec.method,
        "evaluation": spec.evaluation.to_dict(),
        "control_mode": spec.base.control.mode,
        "parameters": [{"path": f.path, "range": [f.low, f.high], "log": f.log} for f in spec.factors],
        "metrics": list(spec.metrics),
        "options": spec.design()["options"],
        "rows": len(row_ids),
        "rows_recorded": len(done),
        "distinct_samples": len(set(row_ids)),
        "failed": sum(1 for r in distinct.values() if r["status"] != "ok"),
        "completed_fraction": None if completed is None or not done else float(np.nansum(completed[[r is not None for r in rows]]) / len(done)),
        "cpu_s_total": float(sum((r.get("cpu_s") or 0.0) for r in distinct.values())),
        "analysis": analyses,
        "strength": {p: ranking[p] for p in ranked},
        "strongest": ranked[:2],
        "files": ["samples.csv", *(["samples.parquet"] if parquet else []), "indices.csv", "summary.json", "summary.md",
                  *(["plots/indices.png"] if spec.method != "uncertainty" else []), "plots/outcome_map.png"],
        "warnings": sample_size_warnings(spec, analyses),
        "notes": [] if parquet else [PARQUET_MISSING],
    }
    atomic_write_text(root / "summary.json", json.dumps(summary, indent=1, allow_nan=False, ensure_ascii=False))
    atomic_write_text(root / "summary.md", summary_markdown(summary))
    plots = root / "plots"
    plots.mkdir(exist_ok=True)
    if spec.method != "uncertainty":
        _plot_indices(spec, analyses, ranked, plots / "indices.png")
    if len(spec.factors) >= 2:
        _plot_outcome_map(spec, values, rows, ranked[:2], plots / "outcome_map.png")
    return summary


def summary_markdown(summary: dict[str, Any]) -> str:
    """The study's indices as markdown tables: one row per parameter (strongest first), one column per metric."""
    if summary["method"] == "uncertainty":
        return uncertainty.markdown(summary)
    morris = summary["method"] == "morris"
    metrics = summary["metrics"]
    lines = [
        f"{summary['method']} study, {summary['control_mode']} loop, {summary['evaluation']['kind']}: "
        f"{summary['rows_recorded']}/{summary['rows']} rows recorded, {summary['failed']} failed evaluations, "
        f"task completed in {_pct(summary.get('completed_fraction'))} of the samples, {summary['cpu_s_total']:.0f} s CPU.",
        "",
        ("μ* ± 95 % (σ) per metric: the mean absolute elementary effect, i.e. the metric's change per full (log) range "
          "of the parameter, measured over steps of 2/3 of that range (4 levels); σ large against μ*: nonlinear or interacting"
         if morris else "S_T ± 95 % (S1 ± 95 %) per metric: the parameter's total (first-order) share of the metric's variance, "
                        "with the bootstrap half-widths"),
        "",
        *[f"- **Warning:** {w}." for w in summary.get("warnings", [])],
        *([""] if summary.get("warnings") else []),
        "| parameter | range | strength | " + " | ".join(f"`{m}`" for m in metrics) + " |",
        "|---|---|---|" + "---|" * len(metrics),
    ]
    ranges = {p["path"]: p for p in summary["parameters"]}
    for path, share in summary["strength"].items():
        r = ranges[path]
        cells = []
        for m in metrics:
            indices = summary["analysis"][m].get("indices")
            if not indices:
                cells.append("–")
                continue
            v = indices[path]
            if morris:
                cells.append(f"{_g(v['mu_star'])} ± {_g(v['mu_star_conf'])} ({_g(v['sigma'])})")
            else:
                cells.append(f"{_g(v['ST'])} ± {_g(v['ST_conf'])} ({_g(v['S1'])} ± {_g(v['S1_conf'])})")
        low, high = r["range"]
        lines.append(f"| `{path}` | {low:g} – {high:g}{' log' if r['log'] else ''} | {share:.2f} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _g(value: float | None) -> str:
    return "–" if value is None else f"{value:.3g}"


def _pct(value: float | None) -> str:
    return "–" if value is None else f"{100 * value:.0f} %"


def _short(path: str) -> str:
    parts = path.split(".")
    return ".".join(parts[-2:]) if len(parts) > 1 else path


def _plot_indices(spec: SensitivitySpec, analyses: dict[str, dict[str, Any]], ranked: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metrics = [m for m in spec.metrics if m != uncertainty.FAILURE]  # a name, not a number
    n = len(metrics)
    cols = min(n, 3)
    grid_rows = math.ceil(n / cols)
    fig, axes = plt.subplots(grid_rows, cols, figsize=(5.0 * cols, 0.45 * len(ranked) * grid_rows + 1.6 * grid_rows),
                             squeeze=False)
    order = list(reversed(ranked))  # strongest on top
    y = np.arange(len(order))
    for ax, metric in zip(axes.flat, metrics):
        indices = analyses[metric].get("indices")
        ax.set_title(metric, fontsize=9)
        ax.set_yticks(y, [_short(p) for p in order], fontsize=7)
        if not indices:
            ax.text(0.5, 0.5, "not enough samples", transform=ax.transAxes, ha="center", fontsize=8)
            continue
        if spec.method == "morris":
            mu_star = [indices[p]["mu_star"] or 0.0 for p in order]
            conf = [indices[p]["mu_star_conf"] or 0.0 for p in order]
            sigma = [indices[p]["sigma"] or 0.0 for p in order]
            ax.barh(y + 0.18, mu_star, 0.36, xerr=conf, color="tab:blue", label="μ* (±95 %)")
            ax.barh(y - 0.18, sigma, 0.36, color="tab:orange", alpha=0.7, label="σ")
            ax.set_xlabel("per full (log) range of the parameter", fontsize=7)
        else:
            s1 = [indices[p]["S1"] or 0.0 for p in order]
            st = [indices[p]["ST"] or 0.0 for p in order]
            ax.barh(y + 0.18, st, 0.36, xerr=[indices[p]["ST_conf"] or 0.0 for p in order], color="tab:blue", label="S_T")
            ax.barh(y - 0.18, s1, 0.36, xerr=[indices[p]["S1_conf"] or 0.0 for p in order], color="tab:orange", label="S1")
        ax.tick_params(axis="x", labelsize=7)
        ax.legend(fontsize=7, loc="lower right")
    for ax in axes.flat[n:]:
        ax.axis("off")
    fig.suptitle(f"{spec.method} sensitivity, {spec.base.control.mode} loop, {spec.evaluation.kind}", fontsize=10)
    atomic_write_figure(fig, path)


def _plot_outcome_map(spec: SensitivitySpec, values: np.ndarray, rows: list[dict[str, Any] | None], pair: list[str],
                      path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    i, j = (spec.paths.index(p) for p in pair)
    xy = values[:, [i, j]].copy()
    if spec.method == "morris":  # Morris points sit on a grid and repeat in projection: spread them a little to show each
        rng = np.random.default_rng(0)
        for c, factor in enumerate((spec.factors[i], spec.factors[j])):
            lo, hi = factor.bounds
            shift = rng.uniform(-0.025, 0.025, len(xy)) * (hi - lo)
            xy[:, c] = xy[:, c] * 10.0**shift if factor.log else xy[:, c] + shift
    completed = outputs(rows, OUTCOME_METRIC)
    recorded = np.array([r is not None for r in rows])
    metrics = [m for m in spec.metrics if m != uncertainty.FAILURE]  # a name, not a number
    n = len(metrics)
    cols = min(n, 3)
    grid_rows = math.ceil(n / cols)
    fig, axes = plt.subplots(grid_rows, cols, figsize=(4.6 * cols, 3.8 * grid_rows), squeeze=False)
    for ax, metric in zip(axes.flat, metrics):
        y = outputs(rows, metric)
        ok = recorded & np.isfinite(y)
        points = ax.scatter(xy[ok, 0], xy[ok, 1], c=y[ok], cmap="viridis", s=70, edgecolors="k", linewidths=0.3)
        failed = recorded & (completed == 0.0) if OUTCOME_METRIC in spec.metrics else np.zeros(len(rows), bool)
        if failed.any():
            ax.scatter(xy[failed, 0], xy[failed, 1], marker="x", c="red", s=16, linewidths=1.0, label="not completed")
            ax.legend(fontsize=7, loc="best")
        if ok.any():
            fig.colorbar(points, ax=ax).ax.tick_params(labelsize=7)
        for axis_setter, factor in ((ax.set_xscale, spec.factors[i]), (ax.set_yscale, spec.factors[j])):
            if factor.log:
                axis_setter("log")
        ax.set_xlabel(pair[0], fontsize=7)
        ax.set_ylabel(pair[1], fontsize=7)
        ax.set_title(metric, fontsize=9)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[n:]:
        ax.axis("off")
    spread = "; Morris grid points spread by ±2.5 % of the range" if spec.method == "morris" else ""
    fig.suptitle(f"outcome over the two strongest parameters (every sample; x: task not completed{spread})", fontsize=10)
    atomic_write_figure(fig, path)
