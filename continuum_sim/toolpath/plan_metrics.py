"""The plan's own figures: duration, clearances, cut-path deviation, IK errors, step sizes."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..distances import polyline_distance
from ..geometry import ArmGeometry
from ..layout import TaskLayout
from .clearance import arm_clearance, plate_clearance, sample_box_gaps
from .config import PlanConfig
from .poses import grinder_poses
from .task_plan import SEGMENT_NAMES, STAGE_NAMES

Array = NDArray[np.float64]


def _closest(name: str, gaps: Array, samples: Array, cat: dict) -> dict:
    """``min_<name>_clearance_m`` / ``_t`` / ``_stage`` of the smallest gap (gaps[i] at plan sample samples[i])."""
    if gaps.size == 0:
        return {f"min_{name}_clearance_m": math.inf, f"min_{name}_clearance_t": None, f"min_{name}_clearance_stage": None}
    j = int(np.argmin(gaps))
    k = int(samples[j])
    return {
        f"min_{name}_clearance_m": float(gaps[j]),
        f"min_{name}_clearance_t": float(cat["t"][k]),
        f"min_{name}_clearance_stage": STAGE_NAMES[int(cat["stage"][k])] + "/" + SEGMENT_NAMES[int(cat["segment"][k])],
    }


def plan_metrics(geometry: ArmGeometry, layout: TaskLayout, cfg: PlanConfig, cat: dict[str, np.ndarray], q_left: Array,
                 q_right: Array, tcp_left: Array, tcp_right: Array, waypoints: dict[str, dict]) -> dict:
    """The figures ``TaskPlan.metrics`` holds, from the sampled plan (``cat``: the concatenated samples)."""
    clearance = arm_clearance(geometry, layout, cfg, q_left, q_right)
    cutting = cat["cutting"]
    # From the retrieval on, the cut-off sample travels with the gripper: keep it clear of the
    # grinder (before that it sits in the plate, the kerf, and so the cutter, beside it by design).
    carried = np.flatnonzero(cat["closed"] & (cat["stage"] >= STAGE_NAMES.index("retrieval")))
    sample_gaps = sample_box_gaps(geometry, layout, cfg, q_left[carried], tcp_right[carried]) if carried.size else np.zeros(0)
    # Deviation of the planned TCP (eq. 12 interpolation between solved points) from the ideal kerf line.
    gp = grinder_poses(layout, cfg)
    line = np.array([gp[k][:3, 3] for k in ("cut_start", "front_edge", "inner_corner", "side_edge")])
    dev = polyline_distance(tcp_left[cutting, :3, 3], line) if cutting.any() else np.zeros(0)
    axis_err = np.degrees(np.arccos(np.clip(tcp_left[cutting, 2, 2], -1.0, 1.0))) if cutting.any() else np.zeros(0)
    steps = {}
    for arm, q in (("left", q_left), ("right", q_right)):
        dq = np.abs(np.diff(q, axis=0))
        steps[arm] = {"max_dtheta_deg_per_sample": float(np.degrees(dq[:, 0::2].max())),
                      "max_dphi_deg_per_sample_bent": float(np.degrees(_bent_dphi(q, cfg.limits.phase_free_below)))}
    wp_err_p = max(float(np.max(w["position_error"])) for w in waypoints.values())
    wp_err_o = max(float(np.max(w["orientation_error"])) for w in waypoints.values())
    return {
        "duration_s": float(cat["t"][-1]),
        "samples": int(cat["t"].size),
        **_closest("arm", clearance, np.arange(clearance.size), cat),  # type: ignore[arg-type]
        **_closest("sample", sample_gaps, carried, cat),  # type: ignore[arg-type]
        "min_plate_clearance_left_m": float(plate_clearance(geometry, layout, q_left, "left").min()),
        "min_plate_clearance_right_m": float(plate_clearance(geometry, layout, q_right, "right").min()),
        "cut_path_max_deviation_m": float(dev.max()) if dev.size else 0.0,
        "cut_path_mean_deviation_m": float(dev.mean()) if dev.size else 0.0,
        "spindle_axis_max_error_deg": float(axis_err.max()) if axis_err.size else 0.0,
        "waypoint_position_error_max_m": wp_err_p,
        "waypoint_orientation_error_max_rad": wp_err_o,
        "waypoints": {k: int(len(v["q"])) for k, v in waypoints.items()},
        "step_limits": steps,
        "cut_duration_s": float(cutting.sum() / cfg.sample_rate_hz),
    }


def _bent_dphi(q: Array, free_below: float) -> float:
    th, ph = q[:, 0::2], q[:, 1::2]
    bent = (th[1:] >= free_below) & (th[:-1] >= free_below)
    d = np.abs(np.diff(ph, axis=0))
    return float(d[bent].max()) if bent.any() else 0.0
