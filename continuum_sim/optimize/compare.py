"""Compare the fronts of two finished design studies of the same objectives (e.g. NSGA-II against a grid).

    python -m continuum_sim.optimize.compare STUDY_A STUDY_B [PLOT.png]

Reads each folder's ``summary.json`` (objectives, directions) and ``trials.csv`` (feasible
completed designs) and prints JSON: each front, how many of B's front points some design of A
weakly dominates (no worse in every objective: "at least as good as"), and the other way
round, and with two objectives the hypervolume of each front against a common reference
point (the worst feasible value of each objective over both studies).
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path
from typing import Any

from .report import pareto_indices


def load(folder: Path) -> tuple[list[str], list[str], list[list[float]], int]:
    summary = json.loads((folder / "summary.json").read_text())
    labels = [o["label"] for o in summary["objectives"]]
    directions = [o["direction"] for o in summary["objectives"]]
    with (folder / "trials.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    points = [[float(r[label]) for label in labels] for r in rows if r["state"] == "COMPLETE" and r["feasible"] == "1"]
    return labels, directions, points, len(rows)


def weakly_dominates(a: list[float], b: list[float], directions: list[str]) -> bool:
    return all((x <= y) if d == "minimize" else (x >= y) for x, y, d in zip(a, b, directions))


def hypervolume_2d(points: list[list[float]], reference: list[float], directions: list[str]) -> float:
    """Area dominated by ``points`` up to ``reference`` (both objectives turned into minimisation)."""
    sign = [1.0 if d == "minimize" else -1.0 for d in directions]
    pts = sorted((sign[0] * p[0], sign[1] * p[1]) for p in points)
    ref = (sign[0] * reference[0], sign[1] * reference[1])
    area, best_y = 0.0, ref[1]
    for x, y in pts:
        if x >= ref[0] or y >= best_y:
            continue
        area += (ref[0] - x) * (best_y - y)
        best_y = y
    return area


def compare(a: Path, b: Path) -> dict[str, Any]:
    labels_a, directions, points_a, n_a = load(a)
    labels_b, directions_b, points_b, n_b = load(b)
    if labels_a != labels_b or directions != directions_b:
        raise SystemExit(f"the studies have different objectives: {labels_a} vs {labels_b}")
    front_a = [points_a[i] for i in pareto_indices(points_a, directions)]
    front_b = [points_b[i] for i in pareto_indices(points_b, directions)]
    out: dict[str, Any] = {
        "objectives": dict(zip(labels_a, directions)),
        "a": {"folder": str(a), "designs": n_a, "feasible": len(points_a), "front": front_a},
        "b": {"folder": str(b), "designs": n_b, "feasible": len(points_b), "front": front_b},
        "b_front_points_matched_by_a": sum(any(weakly_dominates(p, q, directions) for p in points_a) for q in front_b),
        "a_front_points_matched_by_b": sum(any(weakly_dominates(q, p, directions) for q in points_b) for p in front_a),
    }
    if len(labels_a) == 2 and points_a and points_b:
        both = points_a + points_b
        reference = [max(p[k] for p in both) if d == "minimize" else min(p[k] for p in both) for k, d in enumerate(directions)]
        out["hypervolume"] = {"reference": reference, "a": hypervolume_2d(front_a, reference, directions),
                              "b": hypervolume_2d(front_b, reference, directions)}
    return out


def plot(a: Path, b: Path, path: Path) -> None:
    """Both studies' feasible designs and fronts on the first two objectives."""
    import matplotlib

    matplotlib.use("Agg")  # a file only: never a window, never GL
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    labels: list[str] = []
    for folder, colour, marker in ((a, "tab:red", "o"), (b, "tab:blue", "s")):
        labels, directions, points, _ = load(folder)
        name = json.loads((folder / "summary.json").read_text())["sampler"]
        ax.scatter([p[0] for p in points], [p[1] for p in points], s=14, c=colour, marker=marker, alpha=0.35, label=f"{name}: {len(points)} feasible")
        front = sorted(points[i] for i in pareto_indices(points, directions))
        ax.plot([p[0] for p in front], [p[1] for p in front], "-", marker=marker, c=colour, mfc="none", ms=8, label=f"{name} front ({len(front)})")
    ax.set_xlabel(labels[0])
    ax.set_ylabel(labels[1])
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) not in (2, 3):
        print("usage: " + __doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    print(json.dumps(compare(Path(args[0]), Path(args[1])), indent=1))
    if len(args) == 3:
        plot(Path(args[0]), Path(args[1]), Path(args[2]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
