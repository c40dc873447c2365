"""SoRoSim release dynamics, per case: the model with the documented damping map, and with one τ per rod.

    python scripts/sorosim_dynamics_table.py --out validation/sorosim_dynamics_table

Writes ``<out>.md`` / ``<out>.json`` (atomic) and prints the tables; progress on stderr. The .md holds
the per-case table, then one row per rod: the worst case of each variant (docs/validation.md).
Variant ``file τ``: every joint spring k gets c = τ·k with the case's own τ from the file
(the map the report uses). Variant ``one τ``: the rod's mean τ over its 10 cases for all
of them, to show what a single damping value per rod can and cannot match.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from continuum_sim.configio import atomic_write_text  # noqa: E402
from continuum_sim.glbackend import choose_gl_backend  # noqa: E402
from continuum_sim.validation.sorosim import RODS  # noqa: E402
from continuum_sim.validation.sorosim_dynamics import CASES, compare_release, load_release  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rods", nargs="+", default=list(RODS), choices=list(RODS))
    parser.add_argument("--cases", nargs="+", type=int, default=list(CASES))
    parser.add_argument("--out", type=Path, default=Path("validation/sorosim_dynamics_table"))
    args = parser.parse_args(argv)
    choose_gl_backend()
    rows = []
    for name in args.rods:
        rod = RODS[name]
        taus = {k: load_release(rod, k).damping for k in args.cases}
        tau_mean = sum(taus.values()) / len(taus)
        for k in args.cases:
            for variant, scale in (("file τ", 1.0), ("one τ", tau_mean / taus[k])):
                r, _, _ = compare_release(rod, k, damping_scale=scale)
                rows.append(
                    {
                        "rod": name,
                        "case": k,
                        "variant": variant,
                        "tau": taus[k] * scale,
                        "links": r.n_links,
                        "tip_rms_pct": r.tip_rms_pct,
                        "tip_max_pct": r.tip_max_pct,
                        "mid_rms_pct": r.mid_rms_pct,
                        "f_ref": r.frequency_ref,
                        "f_model": r.frequency_model,
                        "f_err_pct": r.frequency_error_pct,
                        "decay_ref": r.decay_ref,
                        "decay_model": r.decay_model,
                        "decay_err_pct": r.decay_error_pct,
                    }
                )
                print(f"{name} {k} {variant}: tip RMS {r.tip_rms_pct:.3f} % L", file=sys.stderr, flush=True)
    head = (
        "| rod | case | damping | τ (ms) | links | tip RMS % L | tip max % L | mid RMS % L | f ref Hz | f err % | σ ref 1/s | σ err % |\n"
        "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n"
    )
    body = "".join(
        f"| {r['rod']} | {r['case']} | {r['variant']} | {1000 * r['tau']:.2f} | {r['links']} | {r['tip_rms_pct']:.3f} | "
        f"{r['tip_max_pct']:.2f} | {r['mid_rms_pct']:.3f} | {r['f_ref']:.3f} | {r['f_err_pct']:+.2f} | "
        f"{r['decay_ref']:.3f} | {r['decay_err_pct']:+.1f} |\n"
        for r in rows
    )
    text = head + body + "\n" + summary_table(rows)
    atomic_write_text(args.out.with_suffix(".md"), text)
    atomic_write_text(args.out.with_suffix(".json"), json.dumps(rows, indent=2) + "\n")
    print(text, end="")
    return 0


def summary_table(rows: list[dict]) -> str:
    """One row per rod: τ range, worst tip RMS, frequency and decay errors of both variants, cases over 1 % L."""
    lines = [
        "| rod | links | τ over the cases (ms) | tip RMS % L, worst (file τ / one τ) | swing frequency error, worst (file τ) "
        "| decay error, worst (file τ / one τ) | cases with tip RMS > 1 % L (file τ / one τ) |",
        "|---|---:|---|---|---:|---|---|",
    ]

    def worst(values: list[float]) -> float:
        return max(values, key=abs)

    for rod in dict.fromkeys(r["rod"] for r in rows):
        file_t = [r for r in rows if r["rod"] == rod and r["variant"] == "file τ"]
        one_t = [r for r in rows if r["rod"] == rod and r["variant"] == "one τ"]
        taus = [1000 * r["tau"] for r in file_t]
        worst_one = max(one_t, key=lambda r: abs(r["decay_err_pct"]))
        lines.append(
            f"| {rod} | {file_t[0]['links']} | {min(taus):.1f}–{max(taus):.1f} "
            f"| {max(r['tip_rms_pct'] for r in file_t):.2f} / {max(r['tip_rms_pct'] for r in one_t):.2f} "
            f"| {worst([r['f_err_pct'] for r in file_t]):+.2f} % "
            f"| {worst([r['decay_err_pct'] for r in file_t]):+.1f} % / {worst_one['decay_err_pct']:+.1f} % (case {worst_one['case']}) "
            f"| {sum(r['tip_rms_pct'] > 1.0 for r in file_t)} of {len(file_t)} / {sum(r['tip_rms_pct'] > 1.0 for r in one_t)} of {len(one_t)} |"
        )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
