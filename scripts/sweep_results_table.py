"""A sweep's results.csv as the Markdown table the docs quote (docs/cutting.md, docs/calibration.md).

    python scripts/sweep_results_table.py sweeps/cutting_band [--scale scene.foam.specific_energy=1e-6] [--only COL ...]

One row per variant in grid order: the swept parameters, then each metric (booleans as yes/no,
the failure name, numbers to 3 significant digits). ``--scale PATH=F`` multiplies a column
(e.g. J/m³ -> MJ/m³); ``--only`` keeps the named metric columns. ``--pivot METRIC`` prints a
two-parameter sweep as a grid instead: rows the first swept path, columns the second, each
cell the task outcome and METRIC (e.g. ``cut_path_deviation_mm.mean``).
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

BOOLEAN = ("task.completed", "sample_detached", "detached_before_cut_complete", "sample_held_at_end", "task.cables_saturated")


def cell(column: str, value: str, scale: float) -> str:
    if value == "":
        return "–"
    if column in BOOLEAN:
        return "yes" if float(value) else "no"
    try:
        x = float(value) * scale
    except ValueError:
        return f"`{value}`"
    return f"{x:.3g}"


def pivot(rows: list[dict[str, str]], params: list[str], metric: str, scale: dict[str, float]) -> None:
    """Rows: params[0]; columns: params[1]; cell: 'completed'/failure and the metric."""
    if len(params) != 2:
        raise SystemExit(f"--pivot needs a two-parameter sweep (this one sweeps {params})")
    r_vals = list(dict.fromkeys(r[params[0]] for r in rows))
    c_vals = list(dict.fromkeys(r[params[1]] for r in rows))
    by = {(r[params[0]], r[params[1]]): r for r in rows}
    p0, p1 = params
    print(f"| {p0} \\ {p1} | " + " | ".join(cell(p1, c, scale.get(p1, 1.0)) for c in c_vals) + " |")
    print("|" + "---|" * (len(c_vals) + 1))
    for rv in r_vals:
        cells = []
        for cv in c_vals:
            r = by.get((rv, cv))
            if r is None or r.get("status", "ok") != "ok":
                cells.append("failed" if r else "–")
                continue
            ok = float(r["task.completed"]) if r.get("task.completed") else 0.0
            outcome = "**completes**" if ok else f"`{r.get('task.failure', '')}`"
            cells.append(f"{outcome} {cell(metric, r.get(metric, ''), scale.get(metric, 1.0))}")
        print(f"| {cell(p0, rv, scale.get(p0, 1.0))} | " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--scale", action="append", default=[], help="PATH=FACTOR")
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--pivot", default=None, metavar="METRIC")
    args = ap.parse_args()
    scale = {k: float(v) for k, v in (s.split("=", 1) for s in args.scale)}
    rows = list(csv.DictReader((args.folder / "results.csv").open()))
    header = list(rows[0])
    params = header[header.index("variant_id") + 1: header.index("status")]  # the swept paths, in grid order
    if args.pivot:
        pivot(rows, params, args.pivot, scale)
        return
    skip = {"index", "variant_id", "status", "error", "wall_s", "cpu_s", "host", "backend", *params}
    metrics = [c for c in rows[0] if c not in skip] if args.only is None else args.only
    cols = params + metrics
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in rows:
        if r.get("status", "ok") != "ok":
            print("| " + " | ".join([*(r[p] for p in params), f"failed: {r.get('error', '')}"]) + " |")
            continue
        print("| " + " | ".join(cell(c, r.get(c, ""), scale.get(c, 1.0)) for c in cols) + " |")


if __name__ == "__main__":
    main()
