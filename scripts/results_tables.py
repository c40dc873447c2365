"""The docs' tables, rendered from the published results (outputs of the stages of dvc.yaml).

    python scripts/results_tables.py default-runs     # README: the default task, closed vs open loop
    python scripts/results_tables.py experiment       # docs/plant.md: the paper's experiment, both loops
    python scripts/results_tables.py paper-result     # docs/calibration.md: P(paper's result) over the ranges
    python scripts/results_tables.py paper-outcomes   # docs/calibration.md: how the other samples ended
    python scripts/results_tables.py table FILE.md [N] # the N-th table (default 1st) of a published .md output
    python scripts/results_tables.py pareto STUDY_DIR  # an optimisation study's front

Each prints one Markdown block (no blank line) that a ``check-block`` marker in the docs compares
with the page (``scripts/check_docs.py``; ``--fix`` rewrites the page from it).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_RUNS = ROOT / "docs" / "results" / "default_runs.json"
PAPER = ROOT / "docs" / "calibration" / "paper_result_open" / "summary.json"


def _load(path: Path) -> dict:
    return json.loads(path.read_text())


def _yes(flag: object) -> str:
    return "yes" if flag else "no"


def default_runs() -> list[str]:
    d = _load(DEFAULT_RUNS)
    rows = [
        "| control | task | cutting error mean / max (mm) | cut-path deviation mean / max (mm) | spindle axis max (°) "
        "| sample cut free / held at end | min arm gap (mm) |",
        "|---|---|---|---|---|---|---|",
    ]
    for mode, label in (("closed", "closed (ours, default)"), ("open", "open (the paper's method; paper: ≤ 2.5 mm mean path deviation)")):
        m = d[mode]
        task = "completed" if m["task"]["completed"] else f"failed: {m['task']['failure']}"
        c, p = m["cutting_tip_error_mm"], m["cut_path_deviation_mm"]
        rows.append(f"| {label} | {task} | {c['mean']:.2f} / {c['max']:.2f} | {p['mean']:.2f} / {p['max']:.2f} | "
                    f"{m['spindle_axis_error_deg']['max']:.2f} | {_yes(m['sample_detached'])} / {_yes(m['sample_held_at_end'])} | "
                    f"{1000 * m['min_arm_distance_m']:.1f} |")
    return rows


def experiment() -> list[str]:
    d = _load(DEFAULT_RUNS)
    o, c = d["open"], d["closed"]

    def cells(m: dict) -> int:
        return int(m["cells_total"]) - int(m["cells_remaining"])

    def total(m: dict) -> int:
        return int(m["cells_total"])

    def clamp(m: dict) -> str:
        e = m["tip_error_mm"]["right"]["clamping"]
        return f"{e['mean']:.2f} / {e['max']:.2f} mm"

    def detach(m: dict) -> str:
        if not m["sample_detached"]:
            return "no"
        early = m.get("detached_before_cut_complete")
        return f"{'before the cut was complete' if early else 'yes'} ({m['detach_time_s']:.1f} s)"

    return [
        "| | open loop (paper's method) | closed loop (default) |",
        "|---|---|---|",
        f"| task | {'completed' if o['task']['completed'] else 'failed: ' + str(o['task']['failure'])} "
        f"| {'completed' if c['task']['completed'] else 'failed: ' + str(c['task']['failure'])} |",
        f"| cut path deviation, plate plane (Fig. 16b metric), mean / max | **{o['cut_path_deviation_mm']['mean']:.2f}** / "
        f"{o['cut_path_deviation_mm']['max']:.2f} mm (paper: ≤ 2.5 mm mean) | {c['cut_path_deviation_mm']['mean']:.3f} / "
        f"{c['cut_path_deviation_mm']['max']:.2f} mm |",
        f"| cutting tip error (3-D), mean / max | {o['cutting_tip_error_mm']['mean']:.2f} / {o['cutting_tip_error_mm']['max']:.2f} mm "
        f"| **{c['cutting_tip_error_mm']['mean']:.3f}** / {c['cutting_tip_error_mm']['max']:.2f} mm |",
        f"| foam kerf-core cells cut | {cells(o)} / {total(o)} | {cells(c)} / {total(c)} |",
        f"| sample detached | {detach(o)} | {detach(c)} |",
        f"| sample held at the end | {_yes(o['sample_held_at_end'])} | {_yes(c['sample_held_at_end'])} |",
        f"| clamping-stage gripper tool error, mean / max | {clamp(o)} | {clamp(c)} |",
        f"| peak cable tension | {o['max_cable_tension_n']:.0f} N | {c['max_cable_tension_n']:.0f} N |",
    ]


def paper_result() -> list[str]:
    s = _load(PAPER)
    a = s["analysis"]["uncertainty"]
    lo, hi = a["interval_95"]
    clo, chi = a["completed_interval_95"]
    return [
        "| open loop over the ranges below | samples | probability | 95 % interval (Clopper–Pearson) |",
        "|---|---|---|---|",
        f"| completes with mean path deviation ≤ 2.5 mm (the paper's result) | {a['successes']} of {a['recorded']} "
        f"| **{100 * a['probability']:.0f} %** | {100 * lo:.0f} – {100 * hi:.0f} % |",
        f"| completes (any path deviation) | {a['completed']} of {a['recorded']} | {100 * a['completed_probability']:.0f} % "
        f"| {100 * clo:.0f} – {100 * chi:.0f} % |",
    ]


def paper_outcomes() -> list[str]:
    s = _load(PAPER)
    a = s["analysis"]["uncertainty"]
    rows = ["| parameter (range) | shipped value (place in range) | success, lower half | success, upper half |", "|---|---|---|---|"]
    for p in s["parameters"]:
        path = p["path"]
        h = a["success_by_half_range"][path]
        b = a["base_position"][path]
        low, high = p["range"]

        def pct(v: float | None) -> str:
            return "–" if v is None else f"{100 * v:.0f} %"

        rows.append(f"| `{path}` ({low:g} – {high:g}) | {b['value']:.4g} ({pct(b['fraction_of_range'])}) | "
                    f"{pct(h['lower']['success'])} of {h['lower']['n']} | {pct(h['upper']['success'])} of {h['upper']['n']} |")
    rows.append("| **ending** | **samples** | | |")
    for why, n in sorted(a["failures"].items(), key=lambda kv: -kv[1]):
        rows.append(f"| {why} | {n} | | |")
    return rows


def pareto(folder: str) -> list[str]:
    """An optimisation study's front (its pareto.csv): trial, objectives, success probability, design."""
    import csv

    root = ROOT / folder
    summary = _load(root / "summary.json")
    objectives = [o.get("label") or o["metric"] for o in summary["objectives"]]  # pareto.csv's column names
    extra = [] if "success_probability" in objectives else ["success_probability"]
    variables = [v["path"] for v in summary["variables"]]
    rows = list(csv.DictReader((root / "pareto.csv").open()))
    head = ["trial", *objectives, *extra, *variables]
    out = ["| " + " | ".join(f"`{h}`" if "." in h else h for h in head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        cells = [row["trial"], *[f"{float(row[o]):.3g}" for o in [*objectives, *extra]],
                 *[f"{float(row[v]):.3g}" for v in variables]]
        out.append("| " + " | ".join(cells) + " |")
    return out


def md_table(path: str, index: str = "1") -> list[str]:
    """The ``index``-th (1-based) Markdown table of a published ``.md`` output, as it stands."""
    lines = (ROOT / path).read_text().splitlines()
    tables, current = [], []
    for line in [*lines, ""]:
        if line.lstrip().startswith("|"):
            current.append(line)
        elif current:
            tables.append(current)
            current = []
    return tables[int(index) - 1]


TABLES = {"default-runs": default_runs, "experiment": experiment, "paper-result": paper_result, "paper-outcomes": paper_outcomes}


def main(argv: list[str]) -> int:
    if argv[:1] == ["pareto"] and len(argv) == 2:
        print("\n".join(pareto(argv[1])))
        return 0
    if argv[:1] == ["table"] and len(argv) in (2, 3):
        print("\n".join(md_table(*argv[1:])))
        return 0
    if len(argv) != 1 or argv[0] not in TABLES:
        print(f"usage: python scripts/results_tables.py {{{'|'.join(TABLES)}}} | table FILE.md [N]", file=sys.stderr)
        return 2
    print("\n".join(TABLES[argv[0]]()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
