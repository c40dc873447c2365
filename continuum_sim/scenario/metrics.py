"""Metrics of a run (SPEC §8) computed from its recorded trajectory.

Pure functions of the recorded arrays: ``compute_metrics(trajectory, plan, config)``
needs nothing from the live simulation, so a run folder's ``trajectory.npz`` (with its
``config.toml``, which gives the plan back) is enough to recompute every number in
``metrics.json`` (``continuum-sim metrics RUN_DIR``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..distances import axis_angle_deg, polyline_distance
from .trajectory import CONTACT_KINDS, Trajectory

if TYPE_CHECKING:
    from ..toolpath import TaskPlan
    from .config import ScenarioConfig

Array = NDArray[np.float64]

# Metrics that depend on the machine, not on the configuration: left out of determinism
# comparisons and of sweep tables.
WALL_CLOCK_METRICS = ("wall_seconds", "wall_real_time_factor", "wall_breakdown_s", "cpu_seconds", "cpu_real_time_factor")


def error_stats(errors_m: Array) -> dict[str, float | None]:
    """mean / RMS / max of an error series, in millimetres (None when empty)."""
    e = np.asarray(errors_m, dtype=float) * 1000.0
    if e.size == 0:
        return {"mean": None, "rms": None, "max": None}
    return {"mean": float(e.mean()), "rms": float(np.sqrt(np.mean(e * e))), "max": float(e.max())}


def per_stage(values: Array, stage: Array, stage_names: tuple[str, ...]) -> dict[str, Any]:
    """error_stats of ``values`` for every stage present in the record."""
    out: dict[str, Any] = {}
    for index, name in enumerate(stage_names):
        mask = stage == index
        if np.any(mask):
            out[name] = error_stats(values[mask])
    out["all"] = error_stats(values)
    return out


SAMPLE_MOVED_M = 1e-3  # the welded sample moving this far on the plate counts as detached early
HELD_DISTANCE_M = 0.05  # a held sample is within this of the gripper's tool centre …
HELD_HEIGHT_M = 0.05  # … and lifted above this height (off the plate's level)
SATURATION_FRACTION = 0.99  # a cable at this fraction of the motors' force rating is saturated

# The named outcomes of a run, first that applies wins (``task_outcome``).
TASK_FAILURES = (
    "diverged",  # the simulation stopped early (non-finite state, MuJoCo warning)
    "partial_run",  # only some stages were run: the task cannot complete
    "detached_early",  # the welded sample moved before the cut freed it (dragged by the gripper)
    "cables_saturated",  # not cut free, and a cable reached the motors' force rating
    "spindle_stalled",  # not cut free, and the spindle stalled under the cutting load
    "cut_incomplete",  # not cut free for any other reason (the cutter missed the kerf)
    "sample_dropped",  # cut free after the cut, not held at the end
)


def task_outcome(metrics: dict[str, Any], all_stages: bool, force_rating: float) -> dict[str, Any]:
    """Whether the task completed and, if not, its first named failure (TASK_FAILURES).

    A variant of a design sweep then records *why* it failed, not only that it did.
    """
    saturated = metrics["max_cable_tension_n"] >= SATURATION_FRACTION * force_rating
    stalls = (metrics.get("cutting") or {}).get("stall_events", 0)
    checks = (
        ("diverged", "diverged" in metrics),
        ("partial_run", not all_stages),
        ("detached_early", metrics["detached_before_cut_complete"]),
        ("cables_saturated", not metrics["sample_detached"] and saturated),
        ("spindle_stalled", not metrics["sample_detached"] and stalls > 0),
        ("cut_incomplete", not metrics["sample_detached"]),
        ("sample_dropped", not metrics["sample_held_at_end"]),
    )
    failure = next((name for name, failed in checks if failed), None)
    return {"completed": failure is None, "failure": failure, "cables_saturated": bool(saturated)}


def compute_metrics(trajectory: Trajectory, plan: TaskPlan, config: ScenarioConfig) -> dict[str, Any]:
    """SPEC §8 metrics of a run, from its trajectory, its plan and its configuration only."""
    tr = trajectory
    stage = tr.stage.astype(int)
    grinder, gripper = tr.arms[tr.tool_arm["grinder"]], tr.arms[tr.tool_arm["gripper"]]
    out: dict[str, Any] = {"control": config.control.controller or config.control.mode}
    out["tip_error_mm"] = {
        arm: per_stage(np.linalg.norm(a.tcp_pos - a.tcp_plan[:, :3, 3], axis=1), stage, tr.stage_names)
        for arm, a in tr.arms.items()
    }
    cutting = plan.cutting[tr.plan_index.astype(int)]
    grinder_err = np.linalg.norm(grinder.tcp_pos - grinder.tcp_plan[:, :3, 3], axis=1)
    out["cutting_tip_error_mm"] = error_stats(grinder_err[cutting])
    # Deviation across the planned cut, in the plate plane (the kerf's own line plus lead-in/out).
    planned_cut = plan.tcp(tr.tool_arm["grinder"])[plan.cutting][:, :2, 3]
    out["cut_path_deviation_mm"] = error_stats(polyline_distance(grinder.tcp_pos[cutting, :2], planned_cut))
    axis_err = axis_angle_deg(grinder.tcp_mat[cutting, :, 2], np.array([0.0, 0.0, 1.0]))
    out["spindle_axis_error_deg"] = {
        "mean": float(axis_err.mean()) if axis_err.size else None,
        "max": float(axis_err.max()) if axis_err.size else None,
    }
    out["min_arm_distance_m"] = float(tr.arm_distance.min())
    forces = tr.contact_force
    out["max_contact_force_n"] = {kind: float(forces[:, k].max()) for k, kind in enumerate(CONTACT_KINDS)}
    out["arms_touched"] = bool(forces[:, CONTACT_KINDS.index("arm_arm")].max() > 0.0)
    tension = np.concatenate([a.cable_tension for a in tr.arms.values()], axis=1)
    out["max_cable_tension_n"] = float(tension.max())
    from .cable_friction import friction_metrics  # lazily: the cable kernels (numba) only where a run is measured

    out["cable_friction"] = friction_metrics(tr, config)
    out["min_cable_tension_n"] = float(tension.min())
    if tr.cutting:
        from ..plant.cut_record import CuttingRecord, cutting_metrics  # lazily: the cutter kernels (numba)

        plate = config.layout.plate
        out["cutting"] = cutting_metrics(CuttingRecord.from_arrays(tr.cutting), plate.kerf_polyline(), plate.kerf_width)
    out["cells_total"] = tr.n_cells
    out["cells_remaining"] = int(np.count_nonzero(np.isnan(tr.cell_removal_times)))
    out["sample_detached"] = tr.detach_time is not None
    out["detach_time_s"] = tr.detach_time
    moved = np.linalg.norm(tr.sample_rel_pos - tr.sample_rel_pos[0], axis=1) > SAMPLE_MOVED_M
    out["detached_before_cut_complete"] = bool(np.any(moved & tr.sample_welded))
    sample, tcp = tr.sample_pos[-1], gripper.tcp_pos[-1]
    out["sample_held_at_end"] = bool(np.linalg.norm(sample - tcp) < HELD_DISTANCE_M and sample[2] > HELD_HEIGHT_M)
    out["timestep_s"] = float(config.model.timestep)  # the step the run used (model.stable_step may divide it)
    out["stages_run"] = list(tr.stages_run)
    out["sim_seconds"] = float(tr.t[-1])
    wall = tr.wall_seconds  # None for a loaded trajectory: recompute_metrics keeps metrics.json's
    out["wall_seconds"] = None if wall is None else float(wall)
    # Simulated seconds per second: of wall time (everything, video included) and of this process's CPU time
    # (time.process_time over plan, build, simulation and metrics; what benchmarks/scenario.py measures).
    # Neither is saved in trajectory.npz (identical runs write identical files): None for a loaded trajectory.
    out["wall_real_time_factor"] = float(tr.t[-1] / wall) if wall is not None and wall > 0 else None
    cpu = tr.cpu_seconds
    out["cpu_seconds"] = cpu
    out["cpu_real_time_factor"] = float(tr.t[-1] / cpu) if cpu else None
    out["wall_breakdown_s"] = dict(tr.wall_breakdown_s)
    if tr.failure is not None:
        out["diverged"] = tr.failure
    out["task"] = task_outcome(out, tuple(tr.stages_run) == tuple(tr.stage_names), config.model.cable_max_force)
    return out
