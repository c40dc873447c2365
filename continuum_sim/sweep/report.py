"""The results table (CSV, Parquet when pyarrow is installed) and the plots of a sweep.

Both are rebuilt from the records, in grid order, so they never depend on the order
variants finished in or on how many times the sweep was resumed.
"""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from ..configio import atomic_write_bytes, atomic_write_figure, atomic_write_text
from .spec import GridAxis, SweepSpec


def table_rows(spec: SweepSpec, records: dict[str, dict[str, Any]]) -> tuple[list[str], list[dict[str, Any]]]:
    """Columns and one row per recorded variant, in grid order."""
    columns = ["index", "variant_id", *spec.paths, "status", "error", *spec.metrics, "wall_s"]
    rows = []
    for variant in spec.variants():
        record = records.get(variant.variant_id)
        if record is None:
            continue
        row: dict[str, Any] = {"index": variant.index, "variant_id": variant.variant_id}
        row.update(variant.param_dict)
        row["status"] = record["status"]
        row["error"] = record.get("error") or ""
        metrics = record.get("metrics") or {}
        for name in spec.metrics:
            row[name] = metrics.get(name)
        row["wall_s"] = record.get("wall_s")
        rows.append(row)
    return columns, rows


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)  # round-trips exactly
    return str(value)


def write_table(spec: SweepSpec, records: dict[str, dict[str, Any]], root: Path) -> list[Path]:
    """results.csv (and results.parquet if pyarrow is importable); returns the paths."""
    columns, rows = table_rows(spec, records)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row.get(c)) for c in columns])
    paths = [root / "results.csv"]
    atomic_write_text(paths[0], buffer.getvalue())
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return paths
    data = {}
    for c in columns:
        values = [row.get(c) for row in rows]
        if c in ("variant_id", "status", "error") or any(isinstance(v, str) for v in values):
            data[c] = pa.array([None if v is None else str(v) for v in values], type=pa.string())
        else:
            data[c] = pa.array([None if v is None else float(v) for v in values], type=pa.float64())
    sink = pa.BufferOutputStream()
    pq.write_table(pa.table(data), sink)
    paths.append(root / "results.parquet")
    atomic_write_bytes(paths[1], sink.getvalue().to_pybytes())
    return paths


def format_table(spec: SweepSpec, records: dict[str, dict[str, Any]], max_rows: int = 60) -> str:
    """A fixed-width text table for the terminal (and the README)."""
    columns, rows = table_rows(spec, records)
    shown = [c for c in columns if c not in ("variant_id", "error", "wall_s")]
    text_rows = [[_short(row.get(c)) for c in shown] for row in rows[:max_rows]]
    widths = [max(len(c), *(len(r[i]) for r in text_rows)) if text_rows else len(c) for i, c in enumerate(shown)]
    lines = ["  ".join(c.rjust(w) for c, w in zip(shown, widths))]
    lines += ["  ".join(v.rjust(w) for v, w in zip(r, widths)) for r in text_rows]
    if len(rows) > max_rows:
        lines.append(f"... {len(rows) - max_rows} more rows in results.csv")
    failed = [row for row in rows if row["status"] != "ok"]
    for row in failed[:10]:
        lines.append(f"variant {row['index']} failed: {row['error']}")
    return "\n".join(lines)


def _short(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


# ---------------------------------------------------------------------------- plots
def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def _log_axis(axis: GridAxis) -> bool:
    values = np.asarray(axis.values, dtype=float)
    return axis.log or (bool(np.all(values > 0)) and values.max() / values.min() >= 20.0)


def _log_ticks(ax, x: np.ndarray) -> None:
    """A log x axis ticked at the grid's own values, written plainly (not 3×10⁰ run into 4×10⁰)."""
    ax.set_xscale("log")
    ax.set_xticks(x, [f"{v:.3g}" for v in x], fontsize=8)
    ax.minorticks_off()


def _values(spec: SweepSpec, records, metric: str) -> np.ndarray:
    """The metric on the grid (NaN where missing or failed), shape = axis lengths."""
    shape = tuple(len(a.values) for a in spec.axes)
    out = np.full(math.prod(shape), np.nan)
    for variant in spec.variants():
        record = records.get(variant.variant_id)
        if record is not None and record["status"] == "ok":
            value = (record.get("metrics") or {}).get(metric)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                out[variant.index] = float(value)
    return out.reshape(shape)


def write_plots(spec: SweepSpec, records: dict[str, dict[str, Any]], root: Path) -> list[Path]:
    """Each metric against each swept parameter; a heat map per metric for two parameters."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = root / "plots"
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    evaluation = spec.evaluation.kind
    for metric in spec.metrics:
        grid = _values(spec, records, metric)
        if not np.any(np.isfinite(grid)):
            continue
        for k, axis in enumerate(spec.axes):
            fig, ax = plt.subplots(figsize=(6.0, 4.2))
            x = np.asarray(axis.values, dtype=float)
            moved = np.moveaxis(grid, k, 0).reshape(len(x), -1)
            others = [a for i, a in enumerate(spec.axes) if i != k]
            n_lines = moved.shape[1]
            combos = list(np.ndindex(*[len(a.values) for a in others])) if others else [()]
            step = max(1, n_lines // 8)  # at most ~8 lines per plot
            for j in range(0, n_lines, step):
                y = moved[:, j]
                label = ", ".join(f"{a.path}={a.values[i]:g}" for a, i in zip(others, combos[j])) or None
                ax.plot(x, y, "o-", ms=4, label=label)
            failed = np.all(~np.isfinite(moved), axis=1)
            if np.any(failed):
                ax.plot(x[failed], np.zeros(int(failed.sum())), "rx", ms=8, label="failed/missing")
            if _log_axis(axis):
                _log_ticks(ax, x)
            ax.set_xlabel(axis.path)
            ax.set_ylabel(metric)
            ax.set_title(f"{evaluation}: {metric} vs {axis.path}", fontsize=10)
            ax.grid(True, which="both", alpha=0.3)
            if others or np.any(failed):
                ax.legend(fontsize=7)
            written.append(atomic_write_figure(fig, out_dir / f"{_safe(metric)}__vs__{_safe(axis.path)}.png", dpi=110))
        if len(spec.axes) == 2:
            written.append(_heatmap(plt, spec, grid, metric, out_dir))
    if len(spec.axes) == 1:
        overview = _overview(plt, spec, records, out_dir)
        if overview is not None:
            written.append(overview)
    return written


def _overview(plt, spec: SweepSpec, records, out_dir: Path) -> Path | None:
    """All metrics of a one-parameter sweep on one page (the figure to show people)."""
    (axis,) = spec.axes
    series = [(m, _values(spec, records, m)) for m in spec.metrics]
    series = [(m, y) for m, y in series if np.any(np.isfinite(y))]
    if not series:
        return None
    cols = 2 if len(series) > 1 else 1
    rows = math.ceil(len(series) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 2.9 * rows), squeeze=False, sharex=True)
    x = np.asarray(axis.values, dtype=float)
    for ax, (metric, y) in zip(axes.flat, series):
        ax.plot(x, y, "o-", ms=4)
        if _log_axis(axis):
            _log_ticks(ax, x)
        ax.set_ylabel(metric, fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes.flat[len(series) :]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel(axis.path)
    fig.suptitle(f"{spec.evaluation.kind} vs {axis.path}", fontsize=11)
    path = atomic_write_figure(fig, out_dir / f"overview__vs__{_safe(axis.path)}.png", dpi=110)
    return path


def _heatmap(plt, spec: SweepSpec, grid: np.ndarray, metric: str, out_dir: Path) -> Path:
    a, b = spec.axes
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    masked = np.ma.masked_invalid(grid)
    image = ax.imshow(masked, origin="lower", aspect="auto", cmap="viridis")
    ax.set_yticks(range(len(a.values)), [f"{v:.3g}" for v in a.values], fontsize=7)
    ax.set_xticks(range(len(b.values)), [f"{v:.3g}" for v in b.values], fontsize=7, rotation=45)
    ax.set_ylabel(a.path)
    ax.set_xlabel(b.path)
    if grid.size <= 150:
        for i in range(grid.shape[0]):
            for j in range(grid.shape[1]):
                text = "×" if not np.isfinite(grid[i, j]) else f"{grid[i, j]:.3g}"
                ax.text(j, i, text, ha="center", va="center", fontsize=6, color="w")
    fig.colorbar(image, ax=ax, label=metric)
    ax.set_title(f"{spec.evaluation.kind}: {metric}", fontsize=10)
    path = atomic_write_figure(fig, out_dir / f"{_safe(metric)}__heatmap.png", dpi=110)
    return path


