"""Run the sample-removal scenario as a pipeline: plan → build → simulate → measure → write.

``run_scenario`` ties the stages together: ``plan_task`` refuses an unreachable task
before anything is written; ``build_run_model`` compiles the scene (with the native cable
path, ``model.cable_path``, and its spatial twin for the video); ``simulate``
(``scenario.simulate``) drives the controller tick by tick with the observers (kerf cutter,
recorder, health check, video, progress bar, and any the caller adds); the recorder's rows
become a typed ``Trajectory``; ``compute_metrics`` is a pure function of it; ``write_run``
writes the run folder. A divergent simulation (MuJoCo warning or non-finite state) stops the
run with ``SimulationDiverged`` after everything computed so far has been written.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from .. import kinematics as kin
from ..configio import atomic_write_bytes, atomic_write_text
from ..controllers import ControlContext, Controller, controller_spec, load_controller
from ..distances import min_backbone_distances
from ..limits import check_run_length, check_scenario
from ..model.handles import SceneHandles
from ..model.options import model_geometry
from ..model.state import set_arm_configuration
from ..plant.cable_path import native_cable_xml, release_data
from ..plant.cable_routing import cable_tendons
from ..toolpath import TaskPlan, plan_task
from . import metrics as met
from .cable_friction import CableFrictionObserver
from .compile_notice import compile_notice
from .config import ScenarioConfig
from .flexure_observer import flexure_observers
from .simulate import (
    CutterObserver,
    HealthCheck,
    NoisyMeasurement,
    Observer,
    ProgressObserver,
    Recorder,
    Simulation,
    simulate,
)
from .trajectory import ArmTrajectory, Trajectory
from .video_observer import VideoObserver


class SimulationDiverged(RuntimeError):
    """The simulation produced a MuJoCo warning or a non-finite state."""


def run_scenario(
    config: ScenarioConfig,
    out_dir: Path | None,
    *,
    video: bool = False,
    stages: tuple[str, ...] | None = None,
    progress: bool = False,
    controller: Controller | None = None,
    observers: Sequence[Observer] = (),
) -> dict[str, Any]:
    """Run the task; write the run folder to ``out_dir`` (if given); return the metrics.

    ``stages`` limits the run to the plan up to the end of the last stage named (metrics of
    those stages only); None runs the whole task. ``controller`` replaces the configured
    one; ``observers`` are extra tick-loop hooks (run after the built-in cutter and
    recorder, before the health check).
    """
    # One line on stderr while numba compiles the kernels its cache lacks (the first run on a fresh clone).
    with compile_notice(enabled=progress):
        return _run(config, out_dir, video=video, stages=stages, progress=progress, controller=controller, observers=observers)


def _run(config: ScenarioConfig, out_dir: Path | None, *, video: bool, stages: tuple[str, ...] | None, progress: bool,
         controller: Controller | None, observers: Sequence[Observer]) -> dict[str, Any]:
    """``run_scenario``'s pipeline."""
    clock = _Clock()
    out = None if out_dir is None else Path(out_dir)
    config = with_stable_step(config)  # stiff cables: a smaller whole fraction of model.timestep
    check_scenario(config)  # refused before planning: arm x segments overlap, MuJoCo steps per control tick
    plan = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    clock.lap("plan")
    stages_run, end_time = plan_extent(plan, stages)
    check_run_length(config, end_time)  # and before building or writing anything: steps per run
    root, model, render_model = build_run_model(config)
    if out is not None:
        start_run_dir(out, config, root, model, render_model)
    sim = make_simulation(config, plan, model, controller or load_controller(controller_spec(config)))
    sim.render_model = render_model
    every = round(1.0 / (config.simulation.record_hz * sim.control_period))
    cutter = CutterObserver(sim, every)
    sim.cutter = cutter.cutter  # what observers show of the cut (the video's kerf and overlay)
    recorder = Recorder(every, cutter)
    friction = CableFrictionObserver(config.model.cable_friction, recorder.every)  # acts inside mj_step
    hooks: list[Observer] = [cutter, recorder, friction, *flexure_observers(config), *observers, HealthCheck()]
    if progress:  # before the video: its bar closes at the end of the physics, then the video's shows the encoding
        hooks.append(ProgressObserver(end_time))
    if video and out is not None:
        hooks.append(VideoObserver(sim, out / "video.mp4", config.simulation, progress=progress))
    clock.lap("model_build_and_setup")
    try:
        result = simulate(sim, int(np.ceil(end_time / sim.control_period)), hooks)
    finally:
        release_data(sim.data)  # the native cable hook (the process-global callback goes back when none is left)
    clock.lap("control_records_video")
    clock.laps["physics_mj_step"] = result.physics_seconds  # inside mj_step: what the run costs if all else were free
    clock.laps["control_records_video"] -= result.physics_seconds
    series = recorder.arrays() | friction.arrays()
    trajectory = make_trajectory(series, sim.handles, plan, cutter, stages_run, result.failure, clock)
    metrics = met.compute_metrics(trajectory, plan, config)
    if out is not None:
        write_run(out, trajectory, metrics, plan, config)
    if result.failure is not None:
        raise SimulationDiverged(f"simulation diverged: {result.failure}; partial results kept in {out}")
    return metrics


class _Clock:
    """Wall-clock laps for ``wall_breakdown_s`` and the run's CPU time (machine-dependent; never compared)."""

    def __init__(self) -> None:
        self.start = self.last = time.perf_counter()
        self.cpu_start = time.process_time()
        self.laps: dict[str, float] = {}

    def lap(self, name: str) -> None:
        """Book the time since the last lap under ``name``."""
        now = time.perf_counter()
        self.laps[name], self.last = now - self.last, now


def plan_extent(plan: TaskPlan, stages: tuple[str, ...] | None) -> tuple[tuple[str, ...], float]:
    """(stages run, simulated end time) of a run limited to ``stages`` (None: the whole plan)."""
    names = tuple(plan.stage_names)
    if stages is None:
        return names, float(plan.t[-1])
    unknown = [s for s in stages if s not in names]
    if unknown:
        raise ValueError(f"stages: unknown stage {unknown[0]!r}; known stages are {', '.join(names)}")
    last = max(names.index(s) for s in stages)
    return tuple(stages), float(plan.t[np.flatnonzero(plan.stage <= last)[-1]])


def with_stable_step(config: ScenarioConfig) -> ScenarioConfig:
    """The configuration with ``model.timestep`` the step the run uses (``model.cable_elasticity.stable_timestep``).

    Resolved once, before anything is planned or built, so the model, the limits, the motor
    loops and the saved ``config.toml`` all see the same step (re-resolving it is a no-op).
    """
    import dataclasses

    from ..model.cable_elasticity import stable_timestep

    h = stable_timestep(config.arm, config.model)  # the physical arm: the model geometry is derived inside
    if h == config.model.timestep:
        return config
    return dataclasses.replace(config, model=dataclasses.replace(config.model, timestep=h))


def build_scene_model(config: ScenarioConfig) -> tuple[Any, mujoco.MjModel]:
    """(mjcf root, compiled MjModel) of the configured scene."""
    from ..model.scene import build_scene

    root = build_scene(config.arm, config.layout, config.model, config.scene)
    return root, mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())


def build_run_model(config: ScenarioConfig) -> tuple[Any, mujoco.MjModel, mujoco.MjModel]:
    """(mjcf root, the model to simulate, the model to render) of the configured scene.

    ``model.cable_path = "native"``: the simulated model carries the cables as fixed tendons
    evaluated by the native kernel (``model.cable_path``), the rendered one is the scene as
    built (spatial tendons, drawn as cables); "spatial": both are the scene as built. Ball
    joints keep the spatial path (a fixed tendon spans scalar joints only).
    """
    if config.model.cable_path == "spatial" or not config.model.tendons or config.model.joint == "ball":
        root, model = build_scene_model(config)
        return root, model, model
    from ..model.scene import build_scene
    from ..plant.cable_path import compile_native

    root = build_scene(config.arm, config.layout, config.model, config.scene)
    model, spatial = compile_native(root)
    return root, model, spatial


def make_simulation(config: ScenarioConfig, plan: TaskPlan, model: mujoco.MjModel, controller: Controller) -> Simulation:
    """The run's state: both arms in the plan's first configuration, ids resolved, controller context."""
    from ..plant.cable_path import make_data

    geometry = model_geometry(config.arm, config.model)
    data = make_data(model)  # registered with the native cable path when the model has one
    handles = SceneHandles.from_model(model, geometry, config.layout)
    for arm in handles.arms:
        set_arm_configuration(model, data, geometry, arm, plan.q(arm)[0], config.model.joint)
    mujoco.mj_forward(model, data)
    control_every = max(1, int(round(1.0 / (config.control.rate_hz * model.opt.timestep))))
    context = ControlContext(plan, geometry, config.layout, config, handles.arms, dict(handles.tool_arm),
                             control_every * model.opt.timestep)
    sim = Simulation(model, data, handles, plan, controller, context, control_every)
    # The motors between commands and cables (docs/plant.md): PI encoder loops, speed and force limits.
    from ..plant.drive import MotorDrive  # (here: numba loads only once a run is built)

    sim.actuate = MotorDrive(model, handles, geometry, config.model, config.scene.tools)
    if config.simulation.tcp_noise_m > 0.0:
        sim.measure = NoisyMeasurement(config.simulation.tcp_noise_m, config.simulation.seed)
    return sim


def make_trajectory(series: dict[str, np.ndarray], handles: SceneHandles, plan: TaskPlan, cutter: CutterObserver,
                    stages_run: tuple[str, ...], failure: str | None, clock: _Clock) -> Trajectory:
    """The typed record from the recorder's rows (derived series computed here, vectorised)."""
    arms = {}
    for arm in handles.arms:
        fields = {name: series[f"{arm}_{name}"] for name in ArmTrajectory.__dataclass_fields__ if name != "q_cmd"}
        arms[arm] = ArmTrajectory(q_cmd=kin.from_bending(series[f"{arm}_w_cmd"]), **fields)
    first, second = handles.arms
    distance = min_backbone_distances(arms[first].disk_pos, handles.disk_radii[first],
                                          arms[second].disk_pos, handles.disk_radii[second])
    clock.lap("metrics")
    c = cutter.cutter
    return Trajectory(
        **{name: series[name] for name in Trajectory._ARRAYS if name != "arm_distance"},
        arm_distance=distance, arms=arms, stage_names=tuple(plan.stage_names), tool_arm=dict(handles.tool_arm),
        cell_removal_times=c.removal_time.copy(), detach_time=c.detach_time, stages_run=stages_run,
        cutting=cutter.cutting.record().arrays(),
        failure=failure, wall_breakdown_s=dict(clock.laps), wall_seconds=clock.last - clock.start,
        cpu_seconds=time.process_time() - clock.cpu_start,
    )


RUN_STATE_KEYS = ("status", "status_reason")  # written into metrics.json by the CLI's run-folder bookkeeping


def recompute_metrics(run_dir: Path) -> dict[str, Any]:
    """``metrics.json`` of a run folder recomputed from its ``config.toml`` and ``trajectory.npz`` alone.

    The plan is made again from the saved configuration (``plan_task`` is deterministic);
    the run-folder state keys (``status``) and the wall-clock keys (machine-dependent, so not
    in the trajectory) are carried over from the folder's metrics.json.
    """
    run_dir = Path(run_dir)
    config = ScenarioConfig.from_toml(run_dir / "config.toml")
    plan = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    metrics = met.compute_metrics(Trajectory.load(run_dir / "trajectory.npz"), plan, config)
    written = run_dir / "metrics.json"
    if written.exists():
        old = json.loads(written.read_text())
        metrics.update({k: old[k] for k in (*RUN_STATE_KEYS, *met.WALL_CLOCK_METRICS) if k in old})  # not in the npz
    return metrics


def metrics_text(metrics: dict[str, Any]) -> str:
    """The exact text of ``metrics.json``."""
    return json.dumps(metrics, indent=2, sort_keys=True)


NATIVE_MODEL_NOTE = """\
<!-- The model this run simulated (continuum_sim, model.cable_path = "native"; docs/architecture.md).
  Every arm cable is a fixed tendon over the joints it spans, all coefficients 0: MuJoCo's own tendon
  length, Jacobian and force are 0, and at every step the native cable kernel (model/cable_path.py),
  called from MuJoCo's passive-force callback, writes each cable's exact length, Jacobian, spring and
  damper force and actuator moments. Plain MuJoCo loads this file (the same bodies, joints, actuators,
  tendons and options: tests/test_scenario.py) but without that callback the cables pull nothing.
  scene_spatial.xml is the same scene with MuJoCo's own spatial tendons: plain MuJoCo simulates it,
  with cable forces that agree with the native path to about 1e-13 relative (tests/test_cable_path.py).
  One run-time edit is not in this file: after compiling, each cable tendon's wrap count is cut to 1
  (model.cable_path.shorten_zero_tendons; speed only, MuJoCo then writes the same zeros). -->
"""


def run_model_files(root: Any, model: mujoco.MjModel, render_model: mujoco.MjModel) -> dict[str, str | bytes]:
    """{file name: content} of a run folder's ``model/``: ``scene.xml`` is the model that was simulated.

    With the native cable path (``model is not render_model``) that is the scene's MJCF with the
    cables as zero-coefficient fixed tendons (``model.cable_path.native_cable_xml``, the text
    ``compile_native`` compiled) and a note on the kernel that drives them; ``scene_spatial.xml``
    is the spatial twin (what the video draws and ``models/`` holds). Assets (none in the
    shipped scene) are written beside them under the names the XML uses.
    """
    xml = root.to_xml_string()
    files: dict[str, str | bytes] = dict(root.get_assets())
    if model is render_model:
        files["scene.xml"] = xml
        return files
    files["scene.xml"] = NATIVE_MODEL_NOTE + native_cable_xml(xml, render_model, cable_tendons(render_model))
    files["scene_spatial.xml"] = xml
    return files


def start_run_dir(out_dir: Path, config: ScenarioConfig, root: Any, model: mujoco.MjModel,
                  render_model: mujoco.MjModel) -> None:
    """Before simulating: the configuration and the model of the run (``run_model_files``)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    config.save_toml(out_dir / "config.toml")
    write_parameters(out_dir, config)
    write_provenance(out_dir, config)
    for name, content in run_model_files(root, model, render_model).items():
        if isinstance(content, bytes):
            atomic_write_bytes(out_dir / "model" / name, content)
        else:
            atomic_write_text(out_dir / "model" / name, content)


def write_parameters(out_dir: Path, config: ScenarioConfig) -> None:
    """``parameters.json``: every registry parameter's value in this run and those that differ from the shipped defaults.

    Schema: ``{"parameters": [{path, name, value, default, unit, status, source, range, log, overridden}],
    "overrides": {path: value}}`` (``continuum_sim.params.registry.records``).
    """
    from ..params.registry import records

    doc = records(config, ScenarioConfig.default())
    atomic_write_text(out_dir / "parameters.json", json.dumps(doc, indent=1, ensure_ascii=False))


def write_provenance(out_dir: Path, config: ScenarioConfig) -> None:
    """``provenance.json`` (``continuum_sim.provenance``): code, configuration and registry hashes, libraries, machine.

    Nothing in it feeds the simulation; the configuration hash is that of the ``config.toml`` text
    (written just before).
    """
    from .. import provenance
    from ..params.registry import registry_sha256

    saved = out_dir / "config.toml"
    text = saved.read_text(encoding="utf-8") if saved.is_file() else provenance.config_toml(config)
    provenance.record(out_dir, provenance.current_command("run"), config_toml=text, registry_sha256=registry_sha256())


def write_run(out_dir: Path, trajectory: Trajectory, metrics: dict[str, Any], plan: TaskPlan,
              config: ScenarioConfig) -> None:
    """After simulating: ``metrics.json``, ``trajectory.npz``, ``plots/``, each atomically.

    Small before large: on a full disk the 3 kB metrics survive the MB-sized trajectory
    that could not be written (docs/errors.md).
    """
    from . import plots

    atomic_write_text(out_dir / "metrics.json", metrics_text(metrics))
    trajectory.save(out_dir / "trajectory.npz")
    plots.write_run_plots(out_dir / "plots", trajectory.series(), plan, config)
    if trajectory.cutting:
        from ..plant.cut_record import CuttingRecord
        from .cut_plots import write_cutting_plots

        plate = config.layout.plate
        write_cutting_plots(CuttingRecord.from_arrays(trajectory.cutting), trajectory.t, plate.kerf_polyline(),
                            plate.kerf_width, out_dir / "plots")
