"""docs/cutting/cutting_sweeps.png: the cutting-load sweeps (docs/sweeps/*_task.toml) side by side.

    python scripts/cutting_sweep_figure.py docs/cutting/cutting_energy docs/cutting/feed_speed [--out FIGURE.png]

Each argument is a sweep's --out folder (its results.csv); the figure goes to ``--out``
(default docs/cutting/cutting_sweeps.png). Per sweep: the cutting force
(mean, max while cutting) and the cutting tip error (mean) against the swept parameter,
with the 0.5 mm goal (log scales where the values span more than a factor 20); variants
where the task did not complete (``task.completed`` when the sweep records it, else: sample
not detached after the cut, or not held at the end, or a stall) are marked with a red cross.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from continuum_sim.configio import atomic_write_figure  # noqa: E402

GOAL_MM = 0.5


def main(folders: list[str], out: str = "docs/cutting/cutting_sweeps.png") -> None:
    fig, axes = plt.subplots(1, len(folders), figsize=(4.5 * len(folders), 3.8), squeeze=False)
    for ax, folder in zip(axes[0], folders):
        rows = list(csv.DictReader(open(Path(folder) / "results.csv")))
        param = next(k for k in rows[0] if "." in k and not k.startswith(("cutting", "tip_error")) and k not in ("variant_id",)
                     and rows[0][k] and k[0].isalpha() and k.split(".")[0] in ("layout", "plan", "scene"))
        ok_rows = [r for r in rows if r["status"] == "ok"]
        x = [float(r[param]) for r in ok_rows]
        err = [float(r["cutting_tip_error_mm.mean"]) for r in ok_rows]
        fmean = [float(r["cutting.force_n.mean"]) for r in ok_rows]
        fmax = [float(r["cutting.force_n.max"]) for r in ok_rows]
        if "task.completed" in rows[0]:  # the run's own outcome (scenario.metrics.task_outcome)
            done = [float(r["task.completed"] or 0) == 1.0 for r in ok_rows]
        else:
            done = [r["sample_detached"] == "1.0" and r["detached_before_cut_complete"] == "0.0" and r["sample_held_at_end"] == "1.0"
                    and float(r["cutting.stall_events"] or 0) == 0 for r in ok_rows]
        ax.plot(x, err, "o-", color="k", label="cutting tip error, mean (mm)")
        ax.axhline(GOAL_MM, color="k", ls=":", lw=1)
        for xi, ei, d in zip(x, err, done):
            if not d:
                ax.plot(xi, ei, "x", color="r", ms=12, mew=2)
        ax.set_xlabel(param)
        ax.set_ylabel("error (mm)")
        if max(err) > 20 * min(err):  # a failing variant's error would flatten the others: log scale
            ax.set_yscale("log")
        ax2 = ax.twinx()
        ax2.plot(x, fmean, "s--", color="tab:orange", label="force mean (N)")
        ax2.plot(x, fmax, "^--", color="tab:red", label="force max (N)")
        ax2.set_ylabel("cutting force (N)")
        if max(fmax) > 20 * min(fmean):
            ax2.set_yscale("log")
        ax.set_title(Path(folder).name + "  (red x: task not completed)", fontsize=9)
        lines = ax.get_legend_handles_labels()[0] + ax2.get_legend_handles_labels()[0]
        labels = ax.get_legend_handles_labels()[1] + ax2.get_legend_handles_labels()[1]
        ax.legend(lines, labels, fontsize=7, loc="upper left")
    atomic_write_figure(fig, out)
    print(f"wrote {out}")


if __name__ == "__main__":
    args = sys.argv[1:]
    if "--out" in args:
        at = args.index("--out")
        main(args[:at] + args[at + 2:], args[at + 1])
    else:
        main(args)
