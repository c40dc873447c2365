"""The cut's plots from its record: the kerf as cut from above, the force and the spindle over time."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..plant.cut_record import CuttingRecord, kerf_profile


def write_cutting_plots(record: CuttingRecord, t: np.ndarray, kerf_polyline: np.ndarray, kerf_width: float,
                        out_dir: Any) -> list[Any]:
    """``cut_kerf.png`` (the kerf as cut from above, its measured centre line against the
    plan: the paper's Fig. 16b from the cut itself) and ``cut_force.png`` (force, torque,
    spindle speed over time, stalls marked)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..configio import atomic_write_figure

    paths = []
    lo, h = record.kerf_map_lo, record.kerf_map_spacing
    _, centres, widths = kerf_profile(record.kerf_map > 0.5, lo, h, np.asarray(kerf_polyline)[:, :2],
                                             step=float(h[:2].min()), search=1.5 * kerf_width)
    fig, ax = plt.subplots(figsize=(6, 5))
    nx, ny = record.kerf_map.shape
    extent = (lo[0] * 1e3, (lo[0] + nx * h[0]) * 1e3, lo[1] * 1e3, (lo[1] + ny * h[1]) * 1e3)
    image = ax.imshow(record.kerf_map.T, origin="lower", extent=extent, cmap="Oranges", vmin=0, vmax=1, interpolation="nearest")
    fig.colorbar(image, ax=ax, shrink=0.8, label="removed fraction of the voxel column")
    line = np.asarray(kerf_polyline)[:, :2] * 1e3
    ax.plot(line[:, 0], line[:, 1], "b--", lw=1, label="planned kerf centre")
    ok = ~np.isnan(widths)
    ax.plot(centres[ok, 0] * 1e3, centres[ok, 1] * 1e3, "k.", ms=2, label="kerf centre measured from the cut")
    pad = 1.5 * kerf_width * 1e3
    ax.set_xlim(line[:, 0].min() - pad, line[:, 0].max() + pad)
    ax.set_ylim(line[:, 1].min() - pad, line[:, 1].max() + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title("the cut from above")
    ax.legend(loc="lower left", fontsize=7)
    paths.append(atomic_write_figure(fig, Path(out_dir) / "cut_kerf.png"))

    s = record.series
    fig, axes = plt.subplots(3, 1, figsize=(8, 6), sharex=True)
    axes[0].plot(t, np.linalg.norm(s["cut_force"][:, :2], axis=1), label="|F| in plane")
    axes[0].plot(t, s["cut_feed_force"], label="against feed")
    axes[0].plot(t, np.abs(s["cut_normal_force"]), label="|across feed|")
    axes[0].set_ylabel("cutting force (N)")
    axes[0].legend(fontsize=7)
    axes[1].plot(t, s["cut_torque"] * 1e3)
    axes[1].set_ylabel("torque (mN·m)")
    axes[2].plot(t, s["cut_spindle_speed"], label="speed")
    axes[2].plot(t, s["spindle_reference"], "--", label="command")
    for ts in record.spindle_stall_times:
        for a in axes:
            a.axvline(ts, color="r", lw=1)
    axes[2].set_ylabel("spindle (rad/s)")
    axes[2].set_xlabel("time (s)")
    axes[2].legend(fontsize=7)
    paths.append(atomic_write_figure(fig, Path(out_dir) / "cut_force.png"))
    return paths
