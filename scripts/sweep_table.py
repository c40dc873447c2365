"""A sweep's results.csv as the Markdown table the docs quote (docs/cutting.md, docs/calibration.md).

    python scripts/sweep_table.py sweeps/cutting_band [--scale scene.foam.specific_energy=1e-6] [--only COL ...]

One row per variant in grid order: the swept parameters, then each metric (booleans as yes/no,
the failure name, numbers to 3 significant digits). ``--scale PATH=F`` multiplies a column
(e.g. J/m³ -> MJ/m³); ``--only`` keeps the named metric columns.
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--scale", action="append", default=[], help="PATH=FACTOR")
    ap.add_argument("--only", nargs="*", default=None)
    args = ap.parse_args()
    scale = {k: float(v) for k, v in (s.split("=", 1) for s in args.scale)}
    rows = list(csv.DictReader((args.folder / "results.csv").open()))
    header = list(rows[0])
    params = header[header.index("variant_id") + 1: header.index("status")]  # the swept paths, in grid order
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
