"""The flexure segment's moment–rotation, linear vs geometrically exact, for docs/model.md.

    PYTHONPATH=$PWD python scripts/flexure_comparison.py [--out docs/flexure_nonlinear.png] [--table docs/model/flexure_comparison.md]
        [--json docs/model/flexure_comparison.json]

Prints the markdown table (every 2° per segment, both bending directions) and the
rotation past which the two differ by more than 10 %; writes the plot. ``--table`` also writes the
table, ``--json`` the onsets, the task's ratios and each leaf's buckling load (per section).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from continuum_sim.configio import atomic_write_text
from continuum_sim.geometry import ArmGeometry
from continuum_sim.plant.leaf_rod import LeafSection
from continuum_sim.validation.flexure_nonlinear import TASK_BEND_DEG, comparison, euler_clamped_load, markdown_table, onset_deg


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/flexure_nonlinear.png")
    parser.add_argument("--table", type=Path, help="also write the table to this Markdown file")
    parser.add_argument("--json", type=Path, help="also write the onsets, task ratios and buckling loads to this JSON file")
    args = parser.parse_args()
    geometry = ArmGeometry()
    entries = comparison(geometry, np.arange(0.0, 10.5, 0.5))
    table = markdown_table(entries, every=4)
    print(table)
    names = ("proximal", "middle", "distal")
    data: dict = {}
    for e in entries:
        lo, hi = e["task_deg"]
        ratio = [float(np.interp(d, e["degrees"], e[w]) / np.interp(d, e["degrees"], e["linear"])) for w in ("worst", "opposite") for d in (lo, hi)]
        sec = geometry.sections[e["section"]]
        leaf = LeafSection(sec.hinge_width, sec.hinge_thickness, geometry.material.youngs_modulus, geometry.material.poisson_ratio)
        buckling = euler_clamped_load(leaf, sec.leaf_length(geometry.disk_thickness))
        opposite = onset_deg(e, "opposite")
        data[names[e["section"]]] = {
            "onset_worst_deg": onset_deg(e), "onset_opposite_deg": None if math.isinf(opposite) else opposite,
            "task_bend_deg": list(TASK_BEND_DEG[e["section"]]), "task_per_segment_deg": [lo, hi],
            "task_ratio_worst": ratio[:2], "task_ratio_opposite": ratio[2:],
            "task_ratio_worst_min": min(ratio[:2]), "task_ratio_worst_max": max(ratio[:2]),
            "task_ratio_opposite_min": min(ratio[2:]), "task_ratio_opposite_max": max(ratio[2:]),
            "buckling_load_n": buckling, "buckling_strain_pct": 100 * buckling / (geometry.material.youngs_modulus * leaf.area),
        }
        print(f"{names[e['section']]}: >10 % from {onset_deg(e):.2f}° (worst) / {onset_deg(e, 'opposite'):.2f}° (opposite) per segment; "
              f"task {lo:.1f}–{hi:.1f}° ({TASK_BEND_DEG[e['section']][0]:g}–{TASK_BEND_DEG[e['section']][1]:g}° of bend): "
              f"nonlinear/linear {ratio[0]:.3f}–{ratio[1]:.3f} (worst), {ratio[2]:.3f}–{ratio[3]:.3f} (opposite)")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8), sharey=False)
    for ax, e in zip(axes, entries):
        ax.plot(e["degrees"], e["linear"], "k--", label="linear (model.stiffness)")
        ax.plot(e["degrees"], e["worst"], "C3", label="nonlinear, one leaf compressed (φ 90°)")
        ax.plot(e["degrees"], e["opposite"], "C0", label="nonlinear, two leaves compressed (φ 270°)")
        lo, hi = e["task_deg"]
        ax.axvspan(lo, hi, color="0.85", label="default task")
        ax.set_title(f"{names[e['section']]} segment")
        ax.set_xlabel("rotation per segment (°)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("moment about the bending axis (N·m)")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    if args.table:
        args.table.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.table, table)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.json, json.dumps(data, indent=2) + "\n")


if __name__ == "__main__":
    main()
