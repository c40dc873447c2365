"""Kinematics report: the run folder the main job writes until the scenario lands.

Writes the resolved arm configuration, tip poses and cable lengths at demonstration
configurations, and a plot of the backbones, so the README's first command already
produces something to look at.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from . import kinematics as kin
from .configio import atomic_write_text
from .geometry import ArmGeometry

DEMO_CONFIGURATIONS_DEG = {
    "straight": (0, 0, 0, 0, 0, 0),
    "c_shape": (45, 0, 45, 0, 45, 0),
    "s_shape": (60, 0, 60, 180, 30, 0),
    "spatial": (30, 0, 45, 90, 60, 200),
    "max_bend": (90, 0, 90, 0, 90, 0),
}


def write_kinematics_report(geometry: ArmGeometry, out_dir: Path) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    geometry.save_toml(out_dir / "config.toml")
    report: dict = {"configurations": {}}
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    for name, q_deg in DEMO_CONFIGURATIONS_DEG.items():
        q = np.radians(q_deg)
        tip = kin.forward_kinematics(geometry, q)
        frames = kin.disk_frames(geometry, q)
        report["configurations"][name] = {
            "q_deg": list(q_deg),
            "tip_position_mm": (1000 * tip[:3, 3]).round(6).tolist(),
            "cable_length_changes_mm": (1000 * kin.cable_length_changes(geometry, q)).round(6).tolist(),
        }
        pts = 1000 * frames[:, :3, 3]
        ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], marker=".", label=name)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_zlabel("z [mm]")
    ax.set_title("Arm backbones (disk centres) at demonstration configurations")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "backbones.png", dpi=120)
    plt.close(fig)
    atomic_write_text(out_dir / "kinematics_report.json", json.dumps(report, indent=2))
    return report
