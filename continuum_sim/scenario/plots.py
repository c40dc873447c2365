"""Plots of a run (SPEC §8): toolpath like paper Fig. 16b, θ/φ like Fig. 9a/11a, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..configio import atomic_write_figure
from .config import ScenarioConfig

STAGE_COLOURS = ("#dddddd", "#cfe3f7", "#f7dccf", "#d8f0d0", "#efe2f7", "#f5f0c8", "#e0e0e0")


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _shade_stages(ax, t: np.ndarray, stage: np.ndarray, names: tuple[str, ...]) -> None:
    edges = np.flatnonzero(np.diff(stage)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [len(t) - 1]])
    seen = set()
    for a, b in zip(starts, ends):
        index = int(stage[a])
        label = names[index] if index not in seen else None
        seen.add(index)
        ax.axvspan(t[a], t[b], color=STAGE_COLOURS[index % len(STAGE_COLOURS)], alpha=0.6, lw=0, label=label)


def toolpath_plot(path: Path, series, plan, config: ScenarioConfig) -> None:
    """Planned vs actual grinder path on the plate (top view), like paper Fig. 16b."""
    plt = _plt()
    cutting = plan.cutting[series["plan_index"].astype(int)]
    milling = series["stage"].astype(int) == list(plan.stage_names).index("milling") if "milling" in plan.stage_names else cutting
    plate = config.layout.plate
    kerf = plate.kerf_polyline()
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2))
    ax = axes[0]
    x0, y0 = plate.corner_x, plate.corner_y
    ax.add_patch(plt.Rectangle((x0 - plate.size[0], y0), plate.size[0], plate.size[1], fc="#f3ead0", ec="#b8a878", label="plate"))
    ax.add_patch(plt.Rectangle((x0 - plate.sample_x, y0), plate.sample_x, plate.sample_y, fc="#f7c9a8", ec="#d08050", label="sample"))
    ax.plot(kerf[:, 0], kerf[:, 1], "k--", lw=1, label="kerf centre line")
    planned = series["left_tcp_plan"][:, :3, 3]
    actual = series["left_tcp_pos"]
    ax.plot(planned[milling, 0], planned[milling, 1], "-", color="#1f77b4", lw=2, label="planned (milling)")
    ax.plot(actual[milling, 0], actual[milling, 1], "-", color="#d62728", lw=1, label="actual (milling)")
    ax.set_aspect("equal")
    margin = 0.03
    ax.set_xlim(kerf[:, 0].min() - margin, kerf[:, 0].max() + margin)
    ax.set_ylim(kerf[:, 1].min() - margin, kerf[:, 1].max() + margin)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("Grinder tool-centre path on the plate (top view)")
    ax.legend(fontsize=8, loc="upper left")
    ax = axes[1]
    t = series["t"]
    err = np.linalg.norm(actual - planned, axis=1) * 1000
    ax.plot(t[cutting], err[cutting], ".", ms=2, color="#d62728", label="cutting")
    ax.plot(t[milling & ~cutting], err[milling & ~cutting], ".", ms=2, color="#7f7f7f", label="approach / exit / return")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tool-centre error [mm]")
    ax.set_title("Grinder error during milling")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    atomic_write_figure(fig, path)


def section_angles_plot(path: Path, series, plan) -> None:
    """θ and φ of each section over time for both arms, like paper Fig. 9a/11a."""
    plt = _plt()
    t = series["t"]
    stage = series["stage"].astype(int)
    names = tuple(plan.stage_names)
    fig, axes = plt.subplots(2, 2, figsize=(12, 7), sharex=True)
    for col, arm in enumerate(("left", "right")):
        q = series[f"{arm}_q_plan"]
        qc = series[f"{arm}_q_cmd"]
        for row, (offset, label) in enumerate(((0, "θ [deg]"), (1, "φ [deg]"))):
            ax = axes[row, col]
            _shade_stages(ax, t, stage, names)
            for k in range(q.shape[1] // 2):
                line = ax.plot(t, np.degrees(q[:, 2 * k + offset]), lw=1.5, label=f"section {k} planned")[0]
                if offset == 0:
                    ax.plot(t, np.degrees(qc[:, 2 * k]), "--", lw=0.8, color=line.get_color(), label=f"section {k} commanded")
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(f"{arm} arm ({'grinder' if arm == 'left' else 'gripper'})")
            if row == 1:
                ax.set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=7, ncol=2, loc="upper left")
    atomic_write_figure(fig, path)


TIP_ERROR_FLOOR_MM = 1e-3  # 1 µm: below it the log axis shows round-off at the first samples, not the arms


def tip_error_plot(path: Path, series, plan) -> None:
    """Tool-centre error of both arms over time, stages shaded (log axis from 1 µm; smaller errors drawn at 1 µm)."""
    plt = _plt()
    t = series["t"]
    fig, ax = plt.subplots(figsize=(12, 4))
    _shade_stages(ax, t, series["stage"].astype(int), tuple(plan.stage_names))
    top = TIP_ERROR_FLOOR_MM
    for arm, colour in (("left", "#d62728"), ("right", "#1f77b4")):
        err = np.linalg.norm(series[f"{arm}_tcp_pos"] - series[f"{arm}_tcp_plan"][:, :3, 3], axis=1) * 1000
        ax.plot(t, np.maximum(err, TIP_ERROR_FLOOR_MM), color=colour, lw=1, label=f"{arm} tool-centre error")
        top = max(top, float(np.nanmax(err, initial=0.0)))
    ax.set_yscale("log")
    ax.set_ylim(TIP_ERROR_FLOOR_MM, 2.0 * top)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("error [mm]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, ncol=4)
    atomic_write_figure(fig, path)


def tension_plot(path: Path, series, plan) -> None:
    """Cable tensions of both arms over time; one legend for both panels (the same cables and stages), on the right."""
    plt = _plt()
    t = series["t"]
    fig, axes = plt.subplots(1, 3, figsize=(13.5, 4), gridspec_kw={"width_ratios": (1.0, 1.0, 0.26)})
    axes[1].sharey(axes[0])
    for ax, arm in zip(axes[:2], ("left", "right")):
        _shade_stages(ax, t, series["stage"].astype(int), tuple(plan.stage_names))
        tension = series[f"{arm}_cable_tension"]
        for c in range(tension.shape[1]):
            ax.plot(t, tension[:, c], lw=0.8, label=f"cable {c // 3}_{c % 3}")
        ax.set_title(f"{arm} arm cable tensions")
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("tension [N]")
    axes[2].axis("off")
    handles, labels = axes[0].get_legend_handles_labels()
    axes[2].legend(handles, labels, fontsize=7, loc="center left", title="cable (section_index), stage", title_fontsize=7)
    atomic_write_figure(fig, path)


def write_run_plots(plot_dir: Path, series, plan, config: ScenarioConfig) -> None:
    toolpath_plot(plot_dir / "toolpath.png", series, plan, config)
    section_angles_plot(plot_dir / "section_angles.png", series, plan)
    tip_error_plot(plot_dir / "tip_error.png", series, plan)
    tension_plot(plot_dir / "cable_tensions.png", series, plan)
