"""Plots of the IK and the task plan: paper Fig. 9/11 style shape parameters and errors,
the plan's toolpaths in 3D, and its time series. Matplotlib Agg, files only."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from . import kinematics as kin
from .configio import atomic_write_figure
from .geometry import ArmGeometry
from .layout import TaskLayout

Array = NDArray[np.float64]
SECTION_COLOURS = ("tab:red", "tab:green", "k")  # paper: Section 3 red, 2 green, 1 black


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_shape_parameters(q: Array, position_error: Array, orientation_error: Array, title: str,
                          path: str | Path) -> None:
    """Paper Fig. 9/11: (a) θ and φ of each section per toolpath point, (b) error per point."""
    plt = _plt()
    q = np.asarray(q)
    steps = np.arange(1, len(q) + 1)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.5))
    for k in range(q.shape[1] // 2):
        c = SECTION_COLOURS[k % len(SECTION_COLOURS)]
        ax.plot(steps, np.degrees(q[:, 2 * k]), "-", color=c, label=f"θ{k} (section {k}, paper S{3 - k})")
        ax.plot(steps, np.degrees(q[:, 2 * k + 1]), ":", color=c, lw=2, label=f"φ{k}")
    ax.set_xlabel("toolpath point")
    ax.set_ylabel("angle [deg]")
    ax.set_title(f"(a) {title}: bending θ (solid) and phase φ (dotted)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    bx.semilogy(steps, np.maximum(1e6 * np.asarray(position_error), 1e-12), "o-", ms=3, label="position error [µm]")
    bx.semilogy(steps, np.maximum(np.asarray(orientation_error), 1e-18), "s-", ms=3, label="orientation error [rad]")
    bx.set_xlabel("toolpath point")
    bx.set_title(f"(b) error per point (max {1e6 * np.max(position_error):.2e} µm)")
    bx.grid(alpha=0.3, which="both")
    bx.legend(fontsize=8)
    atomic_write_figure(fig, path)


def _box_edges(lo: Array, hi: Array) -> list[Array]:
    xs, ys, zs = (lo[0], hi[0]), (lo[1], hi[1]), (lo[2], hi[2])
    edges = []
    for y in ys:
        for z in zs:
            edges.append(np.array([[xs[0], y, z], [xs[1], y, z]]))
    for x in xs:
        for z in zs:
            edges.append(np.array([[x, ys[0], z], [x, ys[1], z]]))
    for x in xs:
        for y in ys:
            edges.append(np.array([[x, y, zs[0]], [x, y, zs[1]]]))
    return edges


def plot_plan_overview(plan, geometry: ArmGeometry, layout: TaskLayout, path: str | Path, snapshots: int = 6) -> None:
    """3D view: plate, kerf, both tool paths coloured by stage, arm backbones at instants."""
    plt = _plt()
    fig = plt.figure(figsize=(9, 8))
    ax = fig.add_subplot(projection="3d")
    plate = layout.plate
    lo = np.array([plate.corner_x - plate.size[0], plate.corner_y, plate.top_z - plate.thickness])
    hi = np.array([plate.corner_x, plate.corner_y + plate.size[1], plate.top_z])
    for e in _box_edges(lo, hi):
        ax.plot(*(1000 * e.T), color="0.5", lw=0.8)
    kerf = plate.kerf_polyline()
    ax.plot(*(1000 * kerf.T), color="orange", lw=3, label="kerf")
    cmap = plt.get_cmap("viridis")
    for arm, tcp, marker in (("left", plan.tcp_left, "-"), ("right", plan.tcp_right, "--")):
        for s, name in enumerate(plan.stage_names):
            m = plan.stage == s
            if m.any():
                ax.plot(*(1000 * tcp[m, :3, 3].T), marker, color=cmap(s / 4), lw=1.5,
                        label=f"{name}" if arm == "left" else None)
    idx = np.linspace(0, plan.n - 1, snapshots).astype(int)
    for i in idx:
        for arm, q, c in (("left", plan.q_left, "tab:blue"), ("right", plan.q_right, "tab:red")):
            frames = kin.disk_frames(geometry, q[i], layout.mount(arm).base_transform())
            ax.plot(*(1000 * frames[:, :3, 3].T), color=c, alpha=0.35, lw=2)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_zlabel("z [mm]")
    ax.set_title("Task plan: TCP paths by stage (left solid, right dashed), backbones at instants")
    ax.legend(fontsize=8, loc="upper left")
    atomic_write_figure(fig, path)


def plot_plan_timeseries(plan, clearance: Array, path: str | Path) -> None:
    """θ, φ of both arms over time with the stages shaded, and the arm-to-arm clearance."""
    plt = _plt()
    fig, axes = plt.subplots(3, 1, figsize=(11, 9), sharex=True)
    for ax, q, name in ((axes[0], plan.q_left, "left (grinder)"), (axes[1], plan.q_right, "right (gripper)")):
        for k in range(q.shape[1] // 2):
            c = SECTION_COLOURS[k]
            ax.plot(plan.t, np.degrees(q[:, 2 * k]), "-", color=c, label=f"θ{k}")
            ax.plot(plan.t, np.degrees(q[:, 2 * k + 1]), ":", color=c, label=f"φ{k}")
        ax.set_ylabel(f"{name}\nangle [deg]")
        ax.legend(fontsize=7, ncol=6, loc="upper right")
    axes[2].plot(plan.t, 1000 * clearance, color="tab:purple")
    axes[2].axhline(0.0, color="k", lw=0.8)
    axes[2].set_ylabel("arm-to-arm\nclearance [mm]")
    axes[2].set_xlabel("t [s]")
    for ax in axes:
        for s in range(len(plan.stage_names)):
            m = plan.stage == s
            if m.any():
                ax.axvspan(plan.t[m].min(), plan.t[m].max(), color=f"C{s}", alpha=0.08)
        ax.grid(alpha=0.3)
    for s, name in enumerate(plan.stage_names):
        m = plan.stage == s
        if m.any():
            axes[0].text(plan.t[m].mean(), axes[0].get_ylim()[1], name, ha="center", va="bottom", fontsize=8)
    atomic_write_figure(fig, path)
