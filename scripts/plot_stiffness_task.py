"""Plot and tabulate the stiffness study (docs/sweeps/stiffness_task.toml) for docs/plant.md.

    continuum-sim sweep docs/sweeps/stiffness_task.toml --out sweeps/stiffness_task
    continuum-sim sweep docs/sweeps/stiffness_gravity_sag.toml --out sweeps/stiffness_sag
    python scripts/plot_stiffness_task.py sweeps/stiffness_task sweeps/stiffness_sag docs/plant_stiffness_task.png

Reads each sweep's records/*.json; prints a Markdown table; writes the figure with the
paper's 2.5 mm mean path error marked.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np


def records(folder: str) -> list[dict]:
    out = []
    for path in sorted(Path(folder, "records").glob("*.json")):
        record = json.loads(path.read_text())
        if record.get("error") is None and record.get("metrics"):
            out.append(record)
    return out


def main() -> None:
    task_dir, sag_dir, figure = sys.argv[1], sys.argv[2], sys.argv[3]
    rows = []
    for r in records(task_dir):
        p, m = r["params"], r["metrics"]
        success = bool(m.get("sample_detached")) and not m.get("detached_before_cut_complete") and bool(m.get("sample_held_at_end"))
        rows.append((p["model.stiffness_scale"], "closed" if p["control.outer_gain"] > 0 else "open", success,
                     m.get("cells_remaining"), m.get("cutting_tip_error_mm.mean"), m.get("cut_path_deviation_mm.mean"),
                     m.get("max_cable_tension_n"), m.get("diverged")))
    sag = {r["params"]["model.stiffness_scale"]: r["metrics"].get("sag_mm") for r in records(sag_dir)}
    rows.sort()
    print("| hinge × | loop | task success | cells left | cutting error mean mm | path deviation mean mm | peak tension N | diverged |")
    print("|---|---|---|---|---|---|---|---|")
    for s, loop, ok, left, cut, dev, peak, div in rows:
        print(f"| {s:.2f} | {loop} | {'yes' if ok else 'no'} | {left:.0f} | {cut:.2f} | {dev:.2f} | {peak:.0f} | {div or 'no'} |")
    print("\n| hinge × | gravity sag mm (grinder arm, open loop, q = 60/0/30/0/0/0°) |\n|---|---|")
    for s in sorted(sag):
        print(f"| {s:.2f} | {sag[s]:.2f} |")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    for loop, marker in (("open", "o-"), ("closed", "s-")):
        sel = [r for r in rows if r[1] == loop]
        x = np.array([r[0] for r in sel])
        axes[0, 0].semilogy(x, [r[4] for r in sel], marker, label=f"{loop}: cutting tip error")
        axes[0, 0].semilogy(x, [r[5] for r in sel], marker, alpha=0.5, label=f"{loop}: path deviation (Fig. 16b)")
        axes[0, 1].plot(x, [r[6] for r in sel], marker, label=loop)
        axes[1, 0].plot(x, [1.0 if r[2] else 0.0 for r in sel], marker, label=loop)
    axes[0, 0].axhline(2.5, color="k", ls="--", label="paper: 2.5 mm")
    axes[0, 0].set_ylabel("mean error (mm)")
    axes[0, 0].legend(fontsize=7)
    axes[0, 1].set_ylabel("peak cable tension (N)")
    axes[0, 1].legend(fontsize=7)
    axes[1, 0].set_ylabel("task success (cut, detached after, held)")
    axes[1, 0].legend(fontsize=7)
    xs = sorted(sag)
    axes[1, 1].plot(xs, [sag[s] for s in xs], "d-")
    axes[1, 1].set_ylabel("gravity sag at the tool (mm)")
    for ax in axes.ravel():
        ax.set_xscale("log")
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("hinge stiffness × (model.stiffness_scale)")
    fig.suptitle("Sample-removal task vs flexure-hinge stiffness (plant of docs/plant.md)")
    fig.tight_layout()
    fig.savefig(figure, dpi=110)


if __name__ == "__main__":
    main()
