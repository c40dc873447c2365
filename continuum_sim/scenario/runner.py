"""Run the sample-removal scenario: plan, build, drive, cut, measure, record (SPEC §5–8).

``run_scenario`` is the whole job: it plans both arms' trajectories, builds and compiles
the scene, drives it through the per-cable motor loops (open or closed loop), lets the
spinning cutter remove the kerf, records the time series, and writes the run folder.
A divergent simulation (MuJoCo warning or non-finite state) stops the run with a clear
``SimulationDiverged`` error after everything computed so far has been written.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..configio import atomic_write_bytes, atomic_write_text
from ..glbackend import choose_gl_backend

choose_gl_backend()

import mujoco  # noqa: E402

from .. import kinematics as kin  # noqa: E402
from ..control import ArmController  # noqa: E402
from ..model.options import model_geometry  # noqa: E402
from ..model.state import set_arm_configuration  # noqa: E402
from . import metrics as met  # noqa: E402
from .config import ScenarioConfig  # noqa: E402

ARMS = ("left", "right")


class SimulationDiverged(RuntimeError):
    """The simulation produced a MuJoCo warning or a non-finite state."""


@dataclass
class SceneHandles:
    """Indices into the compiled model that the runner reads or drives every step."""

    tcp_site: dict[str, int]
    cable_actuators: dict[str, np.ndarray]
    cable_tendons: dict[str, np.ndarray]
    disk_bodies: dict[str, np.ndarray]
    disk_radii: dict[str, np.ndarray]
    spindle_actuator: int
    gripper_actuator: int
    sample_body: int
    plate_body: int
    geom_category: np.ndarray  # per geom: 0 world/other, 1 cutter, 2 gripper, 3 left arm, 4 right arm


def _name2id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    index = mujoco.mj_name2id(model, kind, name)
    if index < 0:
        raise KeyError(f"the scene has no {kind.name.removeprefix('mjOBJ_').lower()} named {name!r}")
    return int(index)


def _handles(model: mujoco.MjModel, config: ScenarioConfig) -> SceneHandles:
    geom = model_geometry(config.arm, config.model)
    n_disks = geom.n_disks - 1
    radii = np.concatenate([[s.disk_diameter / 2] * s.n_segments for s in geom.sections])
    cables = config.arm.cable_names
    act, ten, disks, tcp = {}, {}, {}, {}
    for arm in ARMS:
        act[arm] = np.array([_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in cables(arm)])
        ten[arm] = np.array([_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, n) for n in cables(arm)])
        disks[arm] = np.array([_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{arm}/disk_{i}") for i in range(1, n_disks + 1)])
        tcp[arm] = _name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{arm}/tcp")
    from ..model import scene as scene_mod

    return SceneHandles(
        tcp_site=tcp,
        cable_actuators=act,
        cable_tendons=ten,
        disk_bodies=disks,
        disk_radii={arm: radii for arm in ARMS},
        spindle_actuator=_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "left/grinder/spindle"),
        gripper_actuator=_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "right/gripper/cable"),
        sample_body=_name2id(model, mujoco.mjtObj.mjOBJ_BODY, scene_mod.SAMPLE_BODY),
        plate_body=_name2id(model, mujoco.mjtObj.mjOBJ_BODY, scene_mod.PLATE_BODY),
        geom_category=_geom_categories(model),
    )


CONTACT_KINDS = ("cutter", "gripper", "arm_arm", "arm_world")


def _geom_categories(model: mujoco.MjModel) -> np.ndarray:
    category = np.zeros(model.ngeom, dtype=int)
    for g in range(model.ngeom):
        body = model.body(model.geom_bodyid[g]).name
        name = model.geom(g).name
        if name == "left/grinder/cutter":
            category[g] = 1
        elif body.startswith("right/gripper/"):
            category[g] = 2
        elif body.startswith("left/"):
            category[g] = 3
        elif body.startswith("right/"):
            category[g] = 4
    return category


def _contact_forces(model: mujoco.MjModel, data: mujoco.MjData, category: np.ndarray) -> np.ndarray:
    """Normal contact force (N) summed per kind: cutter, gripper, arm–arm, arm–world."""
    n = data.ncon
    if n == 0:
        return np.zeros(len(CONTACT_KINDS))
    contact = data.contact
    normal = _normal_forces(model, data, n)
    pair = category[contact.geom[:n]]
    low, high = pair.min(axis=1), pair.max(axis=1)
    cutter = (low == 1) | (high == 1)
    gripper = ~cutter & ((low == 2) | (high == 2))
    arm_arm = (low == 3) & (high == 4)
    arm_world = (low == 0) & ((high == 3) | (high == 4))
    return np.array([normal[mask].sum() for mask in (cutter, gripper, arm_arm, arm_world)])


def _normal_forces(model: mujoco.MjModel, data: mujoco.MjData, n: int) -> np.ndarray:
    """|normal force| of the first ``n`` contacts (what ``mj_contactForce`` gives in its first entry).

    With elliptic cones (and condim 1) the normal force is the contact's first constraint
    row; pyramidal cones spread it over the pyramid's edges, so ask MuJoCo for those.
    """
    address = data.contact.efc_address[:n]
    if data.nefc == 0:
        return np.zeros(n)
    if model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC:
        return np.where(address >= 0, np.abs(data.efc_force[np.maximum(address, 0)]), 0.0)
    force = np.zeros(6)
    out = np.zeros(n)
    for i in range(n):
        mujoco.mj_contactForce(model, data, i, force)
        out[i] = abs(force[0])
    return out


def build_scene_model(config: ScenarioConfig):
    """(mjcf root, compiled MjModel) of the configured scene."""
    from ..model.scene import build_scene

    root = build_scene(config.arm, config.layout, config.model, config.scene)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    return root, model


def _check_health(data: mujoco.MjData, baseline: np.ndarray) -> str | None:
    grew = np.flatnonzero(data.warning.number > baseline)
    if grew.size:
        name = mujoco.mjtWarning(int(grew[0])).name
        return f"MuJoCo warning {name} at t = {data.time:.4f} s"
    return None


class _Recorder:
    """Appends one row per record tick; ``arrays()`` stacks them."""

    def __init__(self) -> None:
        self.rows: dict[str, list] = {}

    def add(self, **values: Any) -> None:
        for key, value in values.items():
            self.rows.setdefault(key, []).append(np.array(value, copy=True))

    def arrays(self) -> dict[str, np.ndarray]:
        return {key: np.stack(rows) for key, rows in self.rows.items()}


def run_scenario(
    config: ScenarioConfig,
    out_dir: Path | None,
    *,
    video: bool = False,
    stages: tuple[str, ...] | None = None,
    progress: bool = False,
) -> dict[str, Any]:
    """Run the task; write the run folder to ``out_dir`` (if given); return the metrics.

    ``stages`` limits the run to the plan up to the end of the last stage named (metrics
    of those stages only); None runs the whole task.
    """
    from ..toolpath import plan_task

    wall_start = time.perf_counter()
    out_dir = None if out_dir is None else Path(out_dir)
    geom = model_geometry(config.arm, config.model)
    plan = plan_task(geom, config.layout, config.plan)  # refuses an unreachable task before anything is written
    wall_plan = time.perf_counter() - wall_start
    stage_names = tuple(plan.stage_names)
    if stages is not None:
        unknown = [s for s in stages if s not in stage_names]
        if unknown:
            raise ValueError(f"stages: unknown stage {unknown[0]!r}; known stages are {', '.join(stage_names)}")
        last = max(stage_names.index(s) for s in stages)
        end_time = float(plan.t[np.flatnonzero(plan.stage <= last)[-1]])
    else:
        end_time = float(plan.t[-1])

    root, model = build_scene_model(config)
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        config.save_toml(out_dir / "config.toml")
        from dm_control import mjcf

        mjcf.export_with_assets(root, str(out_dir / "model"), "scene.xml")
    data = mujoco.MjData(model)
    handles = _handles(model, config)
    from ..model.cutting import KerfCutter
    tool_options = config.scene.tools
    dt = model.opt.timestep
    control_every = max(1, int(round(1.0 / (config.control.rate_hz * dt))))
    record_every = max(1, int(round(1.0 / (config.simulation.record_hz * dt))))
    plan_rate = 1.0 / float(plan.t[1] - plan.t[0])

    bases = {arm: config.layout.mount(arm).base_transform() for arm in ARMS}
    tools = {arm: config.layout.mount(arm).tool for arm in ARMS}
    controllers = {
        arm: ArmController(
            geom, config.control, bases[arm], config.arm.tools.length(tools[arm]), config.model.cable_kp,
            roll_free=tools[arm] == "grinder",  # the cutter is axisymmetric (planned in 'axis' mode too)
        )
        for arm in ARMS
    }
    q_plans = {"left": plan.q_left, "right": plan.q_right}
    tcp_plans = {"left": plan.tcp_left, "right": plan.tcp_right}

    # Start in the plan's first configuration with the motors already holding it.
    for arm in ARMS:
        set_arm_configuration(model, data, geom, arm, q_plans[arm][0], config.model.joint)
    mujoco.mj_forward(model, data)
    cutter = KerfCutter(model, data, arm="left")

    def plan_index(t: float) -> int:
        return min(int(round(t * plan_rate)), len(plan.t) - 1)

    def apply_controls(index: int, tick_dt: float) -> None:
        # The gripper holds something fixed while its jaws are shut on the still-welded sample.
        holding = {"left": False, "right": bool(plan.gripper_closed[index]) and not cutter.detached}
        for arm in ARMS:
            site = handles.tcp_site[arm]
            data.ctrl[handles.cable_actuators[arm]] = controllers[arm].update(
                q_plans[arm][index], tcp_plans[arm][index], data.site_xpos[site], data.site_xmat[site], tick_dt,
                holding[arm], -data.actuator_force[handles.cable_actuators[arm]],
            )
        # The gripper motor runs its cable toward open/closed at its speed limit: a step command
        # slammed the jaws onto the plate (12 N contact transient on a 2 N grip).
        target = tool_options.gripper_cable_closed if plan.gripper_closed[index] else tool_options.gripper_cable_open
        current = float(data.ctrl[handles.gripper_actuator])
        reach = tool_options.gripper_cable_speed * tick_dt
        data.ctrl[handles.gripper_actuator] = current + min(max(target - current, -reach), reach)
        data.ctrl[handles.spindle_actuator] = tool_options.spindle_speed if plan.spindle_on[index] else 0.0

    apply_controls(0, 0.0)
    mujoco.mj_forward(model, data)
    baseline = data.warning.number.copy()
    recorder = _Recorder()
    sample_rest = None  # sample pose relative to the plate while welded
    moved_early = False
    failure: str | None = None

    wall_setup = time.perf_counter() - wall_start - wall_plan
    wall_physics = 0.0  # inside mj_step: what the run would cost if everything else were free
    n_ticks = int(np.ceil(end_time / (dt * control_every)))
    # Record on control ticks: every ``record_ticks``-th tick (≥ 1).
    record_ticks = max(1, int(round(record_every / control_every)))
    recorder_video = None
    if video and out_dir is not None:
        from ..video import VideoRecorder

        recorder_video = VideoRecorder(
            model,
            out_dir / "video.mp4",
            config.simulation.cameras,
            config.simulation.video_width,
            config.simulation.video_height,
            config.simulation.video_fps,
            shadows=config.simulation.video_shadows,
        )
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=round(end_time, 2), unit="sim s", desc="scenario", bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} sim s [{elapsed}<{remaining}]")
    try:
        for tick in range(n_ticks):
            index = plan_index(data.time)
            apply_controls(index, control_every * dt)
            if tick % record_ticks == 0:
                rel = _relative_pose(data, handles.plate_body, handles.sample_body)
                if sample_rest is None:
                    sample_rest = rel
                if not cutter.detached and np.linalg.norm(rel - sample_rest) > 1e-3:
                    moved_early = True
                _record(recorder, model, data, handles, plan, index, controllers, cutter)
            # The motor loops run inside MuJoCo every step; set-points change per tick.
            step_start = time.perf_counter()
            mujoco.mj_step(model, data, nstep=control_every)
            wall_physics += time.perf_counter() - step_start
            cutter.update(bool(plan.spindle_on[index]))
            failure = _check_health(data, baseline)
            if failure is None and not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
                failure = f"non-finite state at t = {data.time:.4f} s"
            if failure is not None:
                break
            if recorder_video is not None:
                recorder_video.maybe_capture(data)
            if bar is not None and tick % 100 == 0:
                bar.n = min(round(data.time, 2), bar.total)
                bar.refresh()
    finally:
        if bar is not None:
            bar.n = min(round(data.time, 2), bar.total)  # the last tick may end past the plan
            bar.close()
        if recorder_video is not None:
            recorder_video.close()

    wall_loop = time.perf_counter() - wall_start - wall_plan - wall_setup
    series = recorder.arrays()
    _derive(series, handles)
    wall = time.perf_counter() - wall_start
    metrics = compute_metrics(series, plan, config, cutter, moved_early, stages, wall)
    metrics["wall_breakdown_s"] = {  # where the wall time went (machine-dependent, like wall_seconds)
        "plan": wall_plan,
        "model_build_and_setup": wall_setup,
        "physics_mj_step": wall_physics,
        "control_records_video": wall_loop - wall_physics,
        "metrics": wall - wall_plan - wall_setup - wall_loop,
    }
    if failure is not None:
        metrics["diverged"] = failure
    if out_dir is not None:
        _write_outputs(out_dir, series, metrics, plan, config)
    if failure is not None:
        raise SimulationDiverged(f"simulation diverged: {failure}; partial results kept in {out_dir}")
    return metrics


def _derive(series: dict[str, np.ndarray], handles: SceneHandles) -> None:
    """Series computed from the raw records after the run, vectorised (not per tick)."""
    if not series:
        return
    for arm in ARMS:
        series[f"{arm}_q_cmd"] = kin.from_bending(series.pop(f"{arm}_w_cmd"))
    series["arm_distance"] = met.min_backbone_distances(
        series["left_disk_pos"], handles.disk_radii["left"], series["right_disk_pos"], handles.disk_radii["right"]
    )


def _relative_pose(data: mujoco.MjData, plate: int, sample: int) -> np.ndarray:
    R = data.xmat[plate].reshape(3, 3)
    return R.T @ (data.xpos[sample] - data.xpos[plate])


def _record(recorder: _Recorder, model, data, handles: SceneHandles, plan, index: int, controllers, cutter) -> None:
    values: dict[str, Any] = {"t": data.time, "stage": plan.stage[index], "plan_index": index}
    for arm, q_plan, tcp_plan in (("left", plan.q_left, plan.tcp_left), ("right", plan.q_right, plan.tcp_right)):
        site = handles.tcp_site[arm]
        values[f"{arm}_q_plan"] = q_plan[index]
        values[f"{arm}_w_cmd"] = controllers[arm].last_command  # bending coordinates; q_cmd after the run
        values[f"{arm}_tcp_plan"] = tcp_plan[index]
        values[f"{arm}_tcp_pos"] = data.site_xpos[site]
        values[f"{arm}_tcp_mat"] = data.site_xmat[site].reshape(3, 3)
        values[f"{arm}_cable_length"] = data.ten_length[handles.cable_tendons[arm]]
        values[f"{arm}_cable_tension"] = -data.actuator_force[handles.cable_actuators[arm]]
        values[f"{arm}_cable_common_mode"] = controllers[arm].extra  # tension keeping: shortening per section (m)
        values[f"{arm}_disk_pos"] = data.xpos[handles.disk_bodies[arm]]
    values["sample_pos"] = data.xpos[handles.sample_body]
    values["cells_remaining"] = cutter.cells_remaining
    values["spindle_speed"] = cutter.spindle_speed
    values["contact_force"] = _contact_forces(model, data, handles.geom_category)
    recorder.add(**values)


def compute_metrics(series, plan, config: ScenarioConfig, cutter, moved_early: bool, stages, wall: float) -> dict[str, Any]:
    """SPEC §8 metrics from the recorded series."""
    stage_names = tuple(plan.stage_names)
    stage = series["stage"].astype(int)
    out: dict[str, Any] = {"control": config.control.mode}
    tip_error: dict[str, Any] = {}
    for arm in ARMS:
        err = np.linalg.norm(series[f"{arm}_tcp_pos"] - series[f"{arm}_tcp_plan"][:, :3, 3], axis=1)
        tip_error[arm] = met.per_stage(err, stage, stage_names)
    out["tip_error_mm"] = tip_error
    cutting = plan.cutting[series["plan_index"].astype(int)]
    grinder_err = np.linalg.norm(series["left_tcp_pos"] - series["left_tcp_plan"][:, :3, 3], axis=1)
    out["cutting_tip_error_mm"] = met.error_stats(grinder_err[cutting])
    # Deviation across the planned cut, in the plate plane (the kerf's own line plus lead-in/out).
    planned_cut = plan.tcp_left[plan.cutting][:, :2, 3]
    out["cut_path_deviation_mm"] = met.error_stats(met.polyline_distance(series["left_tcp_pos"][cutting, :2], planned_cut))
    axis_err = met.axis_angle_deg(series["left_tcp_mat"][cutting, :, 2], np.array([0.0, 0.0, 1.0]))
    out["spindle_axis_error_deg"] = {
        "mean": float(axis_err.mean()) if axis_err.size else None,
        "max": float(axis_err.max()) if axis_err.size else None,
    }
    out["min_arm_distance_m"] = float(series["arm_distance"].min())
    forces = series["contact_force"]
    out["max_contact_force_n"] = {kind: float(forces[:, k].max()) for k, kind in enumerate(CONTACT_KINDS)}
    out["arms_touched"] = bool(forces[:, CONTACT_KINDS.index("arm_arm")].max() > 0.0)
    tension = np.concatenate([series["left_cable_tension"], series["right_cable_tension"]], axis=1)
    out["max_cable_tension_n"] = float(tension.max())
    out["min_cable_tension_n"] = float(tension.min())
    out["cells_total"] = cutter.n_cells
    out["cells_remaining"] = cutter.cells_remaining
    out["sample_detached"] = bool(cutter.detached)
    out["detach_time_s"] = cutter.detach_time
    out["detached_before_cut_complete"] = bool(moved_early)
    out["sample_held_at_end"] = _sample_held(series, config)
    out["stages_run"] = list(stages) if stages is not None else list(stage_names)
    out["sim_seconds"] = float(series["t"][-1])
    out["wall_seconds"] = float(wall)
    out["real_time_factor"] = float(series["t"][-1] / wall) if wall > 0 else None
    return out


def _sample_held(series, config: ScenarioConfig) -> bool:
    """Held = detached, near the gripper's tool centre, and lifted off the plate's level."""
    sample = series["sample_pos"][-1]
    tcp = series["right_tcp_pos"][-1]
    near = np.linalg.norm(sample - tcp) < 0.05
    return bool(near and sample[2] > 0.05)


def _write_outputs(out_dir: Path, series, metrics, plan, config: ScenarioConfig) -> None:
    import io

    buffer = io.BytesIO()
    np.savez_compressed(buffer, **series, stage_names=np.array(plan.stage_names))
    atomic_write_bytes(out_dir / "trajectory.npz", buffer.getvalue())
    from . import plots

    plots.write_run_plots(out_dir / "plots", series, plan, config)
    atomic_write_text(out_dir / "metrics.json", json.dumps(metrics, indent=2, sort_keys=True))
