"""Tables for docs/kinematics-and-planning.md and docs/architecture.md, rendered from stored results.

    python scripts/docs_tables.py ik docs/results/ik_full.json docs/results/ik_axis.json   # IK speed/accuracy
    python scripts/docs_tables.py ik-accuracy docs/results/ik_full.json    # random poses, the four IK modes
    python scripts/docs_tables.py drift-targets       # the drift study's targets (tests/data/reference_tolerance.json)
    python scripts/docs_tables.py drift-tolerances    # selected metrics: reference value and stored tolerance
    python scripts/docs_tables.py drift-summary       # JSON: leaf counts, the largest tolerance relative to its metric

The IK files are the outputs of ``benchmarks/ik.py --out`` (stage ``ik-benchmark``); the drift
tables read ``tests/data/reference_tolerance.json`` (``scripts/drift_study.py --write``, the file
the stored-reference test uses) and ``tests/data/reference_metrics.json``. Each table prints as
one Markdown block (no blank line) that a ``check-block`` marker compares with the page
(``scripts/check_docs.py``; ``--fix`` rewrites the page from it).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
DATA = ROOT / "tests" / "data"

# The metrics the tolerance table shows (every leaf is in reference_tolerance.json's "atol").
DRIFT_METRICS = (
    "cutting_tip_error_mm.mean", "cutting_tip_error_mm.max", "cut_path_deviation_mm.mean", "spindle_axis_error_deg.max",
    "tip_error_mm.left.all.mean", "tip_error_mm.right.all.mean", "min_arm_distance_m", "max_cable_tension_n",
    "cutting.force_n.mean", "cable_friction.tension_loss_mean_percent", "detach_time_s",
)


def _load(path: str | Path) -> dict:
    return json.loads((ROOT / path).read_text())


def _sci(x: float) -> str:
    """One significant digit, scientific; 0 as 0."""
    return f"{x:.0e}" if x else "0"


def _pct(rate: float) -> str:
    return f"{100 * rate:.3g}%"


def ik(full_path: str, axis_path: str) -> list[str]:
    full, axis = _load(full_path), _load(axis_path)

    def ours(d: dict, kind: str, errors: bool = False) -> str:
        s = d["this_solver"][kind]
        text = f"{s['median_cpu_ms']:.2f} ms, {_pct(s['success_rate'])}"
        if errors:
            text += f" success, max error {s['position_error_max_m']:.1g} m / {s['orientation_error_max_rad']:.1g} rad"
        return text

    def theirs(d: dict, kind: str, errors: bool = False) -> str:
        s = d["baseline_slsqp"][kind]
        text = f"{s['median_cpu_ms']:.3g} ms, {_pct(s['success_rate'])}"
        if errors:
            text += (f" success at 1e-9 (median error {s['position_error_median_m']:.1g} m, "
                     f"max {s['position_error_max_m']:.1g} m)")
        return text

    def ratio(d: dict, kind: str) -> float:
        return d["baseline_slsqp"][kind]["median_cpu_ms"] / d["this_solver"][kind]["median_cpu_ms"]

    return [
        "| | this solver, full | SLSQP (numerical gradients), full | this solver, axis | SLSQP, axis |",
        "|---|---|---|---|---|",
        f"| warm start (previous solution) | {ours(full, 'warm', True)} | {theirs(full, 'warm', True)} | "
        f"{ours(axis, 'warm')} | {theirs(axis, 'warm')} |",
        f"| cold start | {ours(full, 'cold')} | {theirs(full, 'cold')} (straight arm + 3 seeds) | "
        f"{ours(axis, 'cold')} | {theirs(axis, 'cold')} |",
        f"| along the path (`solve_path`, step limits) | {full['this_solver']['path']['per_point_cpu_ms']:.2f} ms | | "
        f"{axis['this_solver']['path']['per_point_cpu_ms']:.2f} ms | |",
        f"| speed ratio (warm / cold, CPU) | {ratio(full, 'warm'):.0f}× / {ratio(full, 'cold'):.0f}× | | "
        f"{ratio(axis, 'warm'):.0f}× / {ratio(axis, 'cold'):.0f}× | |",
    ]


def ik_accuracy(full_path: str) -> list[str]:
    acc = _load(full_path)["accuracy_random_poses"]
    rows = ["| mode (orientation / phase) | targets | success | largest position error (m) | largest orientation error (rad) |",
            "|---|---:|---:|---:|---:|"]
    for mode, d in acc.items():
        rows.append(f"| {mode} | {d['targets']} | {_pct(d['success_rate'])} | {d['position_error_max_m']:.2g} | "
                    f"{d['orientation_error_max_rad']:.2g} |")
    return rows


def _target_label(t: dict) -> str:
    parts = [] if t["numba_cpu"] == "host" else [f"`NUMBA_CPU_NAME={t['numba_cpu']}`"]
    parts += [f"`{k}={v}`" for k, v in sorted(t["env"].items())]
    return " + ".join(parts) or "host (no overrides)"


def drift_targets() -> list[str]:
    study = _load(DATA / "reference_tolerance.json")
    rows = ["| target | numba CPU | OpenBLAS core | metric leaves ≠ host run | ≠ stored reference "
            "| largest relative difference from the reference | cutting error mean (mm) |",
            "|---|---|---|---:|---:|---:|---|"]
    for t in study["targets"]:
        rows.append(f"| {_target_label(t)} | {t['numba_cpu']} | {', '.join(t['openblas_cores'])} | "
                    f"{t['leaves_differing_from_host']} | {t['leaves_differing_from_reference']} | "
                    f"{_sci(t['max_rel_vs_reference'])} | {t['cutting_tip_error_mean_mm']:.10f} |")
    return rows


def _reference() -> dict:
    from continuum_sim.scenario.metric_compare import flatten

    return flatten(_load(DATA / "reference_metrics.json"))


def drift_tolerances() -> list[str]:
    atol, ref = _load(DATA / "reference_tolerance.json")["atol"], _reference()
    rows = ["| metric | reference | tolerance (atol) | tolerance / reference |", "|---|---:|---:|---:|"]
    for key in DRIFT_METRICS:
        rel = atol[key] / abs(ref[key]) if ref[key] else float("nan")
        rows.append(f"| `{key}` | {ref[key]:.7g} | {atol[key]:.2g} | {_sci(rel)} |")
    return rows


def drift_summary() -> dict:
    study, ref = _load(DATA / "reference_tolerance.json"), _reference()
    atol = study["atol"]
    floor = study["abs_floor"]
    # relative to the metric, over the leaves whose tolerance is above the absolute floor (those near zero get the floor)
    rel = sorted(((atol[k] / abs(ref[k]), k) for k in atol if ref[k] and atol[k] > floor), reverse=True)
    at_floor = sorted(k for k in atol if atol[k] <= floor)
    return {"continuous_leaves": len(atol), "targets": len(study["targets"]),
            "largest_atol_percent": 100 * rel[0][0], "largest_atol_metric": rel[0][1],
            "second_atol_percent": 100 * rel[1][0], "second_atol_metric": rel[1][1],
            "leaves_at_abs_floor": len(at_floor), "margin": study["margin"], "rel_floor": study["rel_floor"],
            "abs_floor": floor, "outcome_leaves": sum(1 for v in ref.values() if not isinstance(v, float))}


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__, file=sys.stderr)
        return 2
    name, args = argv[0], argv[1:]
    if name == "drift-summary":
        print(json.dumps(drift_summary(), indent=2))
        return 0
    table = {"ik": ik, "ik-accuracy": ik_accuracy, "drift-targets": drift_targets, "drift-tolerances": drift_tolerances}
    if name not in table:
        print(f"unknown table {name!r}; choose from {sorted([*table, 'drift-summary'])}", file=sys.stderr)
        return 2
    print("\n".join(table[name](*args)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
