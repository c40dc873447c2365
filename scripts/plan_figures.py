"""The default task plan's figures and the cooperative workspace: one JSON for docs/kinematics-and-planning.md.

    python scripts/plan_figures.py --out docs/results/plan_figures.json     # ~1 min CPU on 2 cores

Plans the task as ``continuum-sim plan`` does with its defaults (``ArmGeometry.default()``,
``TaskLayout()``, ``PlanConfig()``: the shipped scenario's arm, layout and plan), solves the
in-plane demo path in both phase modes (``solve_planar_demo``, paper Fig. 10/11) and samples the
workspace as ``continuum-sim workspace`` does (``WorkspaceConfig()``: 200 000 configurations per
arm, 1 cm voxels). Writes ``plan`` (``TaskPlan.metrics`` as the planner returns them),
``planar_demo``, ``workspace`` (``CooperativeWorkspace.summary()``) and ``figures``: the numbers
the page quotes, in the units it quotes them (mm, µm, degrees). Deterministic: no timing.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from continuum_sim import ArmGeometry  # noqa: E402
from continuum_sim.configio import atomic_write_text  # noqa: E402
from continuum_sim.layout import TaskLayout  # noqa: E402
from continuum_sim.toolpath import PlanConfig, plan_task, solve_planar_demo  # noqa: E402
from continuum_sim.workspace import WorkspaceConfig, compute_workspace  # noqa: E402


def planar_demo(geometry: ArmGeometry, layout: TaskLayout, cfg: PlanConfig) -> dict:
    """Both phase modes of the in-plane demo path: success, errors, and how far φ is from {0, π}."""
    out = {}
    for phase, sol in solve_planar_demo(geometry, layout, cfg).items():
        phi = np.mod(np.asarray(sol.q)[:, 1::2], np.pi)  # 0 for φ ∈ {0, π}
        off_plane = np.minimum(phi, np.pi - phi)
        out[phase] = {
            "success": bool(sol.success),
            "points": int(len(sol.q)),
            "position_error_max_m": float(sol.position_error.max()),
            "orientation_error_max_rad": float(sol.orientation_error.max()),
            "phi_off_plane_max_rad": float(off_plane.max()),
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="JSON file to write")
    args = parser.parse_args()
    geometry, layout, cfg = ArmGeometry.default(), TaskLayout(), PlanConfig()
    m = plan_task(geometry, layout, cfg).metrics
    demo = planar_demo(geometry, layout, cfg)
    ws = compute_workspace(geometry, layout, WorkspaceConfig()).summary()
    steps = m["step_limits"]
    figures = {
        "duration_s": m["duration_s"],
        "cut_duration_s": m["cut_duration_s"],
        "waypoint_position_error_max_m": m["waypoint_position_error_max_m"],
        "waypoint_orientation_error_max_rad": m["waypoint_orientation_error_max_rad"],
        "cut_path_max_deviation_um": 1e6 * m["cut_path_max_deviation_m"],
        "spindle_axis_max_error_deg": m["spindle_axis_max_error_deg"],
        "min_arm_clearance_mm": 1e3 * m["min_arm_clearance_m"],
        "min_sample_clearance_mm": 1e3 * m["min_sample_clearance_m"],
        "min_plate_clearance_left_mm": 1e3 * m["min_plate_clearance_left_m"],
        "min_plate_clearance_right_mm": 1e3 * m["min_plate_clearance_right_m"],
        "max_dtheta_deg_per_sample": max(s["max_dtheta_deg_per_sample"] for s in steps.values()),
        "max_dphi_deg_per_sample_bent": max(s["max_dphi_deg_per_sample_bent"] for s in steps.values()),
        "planar_demo_phi_off_plane_max_rad": demo["planar"]["phi_off_plane_max_rad"],
        "planar_demo_planar_success": demo["planar"]["success"],
        "workspace_left_m3": ws["left_volume_m3"],
        "workspace_right_m3": ws["right_volume_m3"],
        "workspace_overlap_m3": ws["overlap_volume_m3"],
    }
    result = {"command": "python scripts/plan_figures.py --out " + str(args.out), "figures": figures,
              "plan": m, "planar_demo": demo, "workspace": ws}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out, json.dumps(result, indent=2, sort_keys=True) + "\n")
    print(json.dumps(figures, indent=2))


if __name__ == "__main__":
    main()
