"""The tick loop: one flat ``simulate`` that drives a controller and calls observers.

Per control tick (every ``control_every`` physics steps)::

    state    = measure(sim)                      # MeasuredState from MjData (sensors)
    commands = controller.command(state)         # MotorCommands
    actuate(sim, commands)                       # default apply_commands: writes data.ctrl
    observer.before_tick(sim)      for each      # e.g. the recorder
    repeat control_every times:
        observer.before_physics_step(sim)        # per-step forces (only observers that define it)
        mujoco.mj_step(model, data)
        observer.after_physics_step(sim)
    observer.after_tick(sim)       for each, in order; a returned str stops the run (failure)

Observers subclass ``Observer`` and override only the hooks they need; the loop runs
MuJoCo's batched ``mj_step(nstep=control_every)`` when no observer has a per-physics-step
hook, so plain runs pay nothing for the hook. A new per-step physics effect (cutting
forces, cable friction, a motor model) is an observer passed to ``run_scenario(...,
observers=[...])``: it may write ``data.qfrc_applied``/``data.xfrc_applied`` or, for a
motor model, overwrite ``data.ctrl`` from ``sim.commands`` before each physics step.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from ..controllers import ArmMeasurement, ControlContext, Controller, MeasuredState, MotorCommands
from ..model.handles import GeomKind, SceneHandles
from ..toolpath import TaskPlan
from .trajectory import CONTACT_KINDS


@dataclass
class Simulation:
    """Everything a tick and its hooks can read: model, data, handles, plan, controller, clock."""

    model: mujoco.MjModel
    data: mujoco.MjData
    handles: SceneHandles
    plan: TaskPlan
    controller: Controller
    context: ControlContext
    control_every: int  # physics steps per control tick
    tick: int = -1  # -1: the priming call before the first step
    plan_index: int = 0
    state: MeasuredState | None = None  # last measurement
    commands: MotorCommands | None = None  # last commands (what a motor model would track)
    measure: Callable[[Simulation], MeasuredState] = field(default=lambda sim: measure_state(sim))
    actuate: Callable[[Simulation, MotorCommands], None] = field(default=lambda sim, c: apply_commands(sim, c))

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    @property
    def control_period(self) -> float:
        return self.control_every * self.timestep

    def plan_index_at(self, t: float) -> int:
        plan_t = self.plan.t
        rate = 1.0 / float(plan_t[1] - plan_t[0])
        return min(int(round(t * rate)), len(plan_t) - 1)


class Observer:
    """Hooks into the tick loop; every hook is optional (override what you need)."""

    def start(self, sim: Simulation) -> None:
        """After the initial state and the priming commands, before the first tick."""

    def before_tick(self, sim: Simulation) -> None:
        """Commands applied to ``data.ctrl``, physics not yet stepped (the recorder reads here)."""

    def before_physics_step(self, sim: Simulation) -> None:
        """Before every ``mj_step``: apply per-step forces (``data.qfrc_applied``, ``xfrc_applied``) or ctrl."""

    def after_physics_step(self, sim: Simulation) -> None:
        """After every ``mj_step``."""

    def after_tick(self, sim: Simulation) -> str | None:  # noqa: ARG002 - a no-op default hook
        """After the tick's physics steps; return a message to stop the run (it is recorded as the failure)."""
        return None

    def close(self, sim: Simulation) -> None:
        """Always called at the end (also after a failure or an exception)."""


def _overrides(observer: Observer, hook: str) -> bool:
    return getattr(type(observer), hook) is not getattr(Observer, hook)


def measure_state(sim: Simulation) -> MeasuredState:
    """The controller's view of ``sim.data``: tool poses, cable tensions and lengths, detachment."""
    data, h = sim.data, sim.handles
    arms = {}
    for arm in h.arms:
        site = h.tcp_site[arm]
        arms[arm] = ArmMeasurement(
            tcp_pos=data.site_xpos[site].copy(),
            tcp_mat=data.site_xmat[site].reshape(3, 3).copy(),
            cable_tension=-data.actuator_force[h.cable_actuators[arm]],
            cable_length=data.ten_length[h.cable_tendons[arm]],
        )
    dt = 0.0 if sim.tick < 0 else sim.control_period
    return MeasuredState(float(data.time), dt, sim.plan_index, arms, not bool(data.eq_active[h.sample_weld]))


class NoisyMeasurement:
    """``measure_state`` plus seeded Gaussian noise on each arm's measured tool-centre position."""

    def __init__(self, std_m: float, seed: int) -> None:
        self.std = float(std_m)
        self.rng = np.random.default_rng(seed)

    def __call__(self, sim: Simulation) -> MeasuredState:
        state = measure_state(sim)
        for arm in sorted(state.arms):
            m = state.arms[arm]
            m.tcp_pos[:] += self.rng.normal(0.0, self.std, 3)
        return state


def apply_commands(sim: Simulation, commands: MotorCommands) -> None:
    """Write the motor commands into the actuators' controls: where commands meet the plant."""
    data, h = sim.data, sim.handles
    for arm in h.arms:
        data.ctrl[h.cable_actuators[arm]] = commands.cable_lengths[arm]
    data.ctrl[h.gripper_actuator] = commands.gripper_cable
    data.ctrl[h.spindle_actuator] = commands.spindle_speed


@dataclass
class SimResult:
    ticks: int  # control ticks run
    failure: str | None  # message of the hook that stopped the run
    physics_seconds: float  # wall time inside mj_step


def prime(sim: Simulation) -> None:
    """Reset the controller and apply its first commands (dt = 0) to the initial state."""
    sim.controller.reset(sim.context)
    sim.tick, sim.plan_index = -1, 0
    sim.state = sim.measure(sim)
    sim.commands = sim.controller.command(sim.state)
    sim.actuate(sim, sim.commands)
    mujoco.mj_forward(sim.model, sim.data)


class TickLoop:
    """The tick loop one tick at a time: ``simulate`` runs it to the end, ``env`` one agent step at a time.

    Construction primes the controller and calls every observer's ``start``; ``tick()`` runs one
    control tick and returns the failure message of the observer that stopped it (or None);
    ``close()`` calls every observer's ``close``.
    """

    def __init__(self, sim: Simulation, observers: Sequence[Observer] = ()) -> None:
        self.sim = sim
        self.observers = list(observers)
        self.before_step = [o for o in self.observers if _overrides(o, "before_physics_step")]
        self.after_step = [o for o in self.observers if _overrides(o, "after_physics_step")]
        self.ticks = 0
        self.physics_seconds = 0.0  # wall time inside mj_step
        prime(sim)
        for o in self.observers:
            o.start(sim)

    def tick(self) -> str | None:
        sim, data = self.sim, self.sim.data
        sim.tick = self.ticks
        sim.plan_index = sim.plan_index_at(data.time)
        sim.state = sim.measure(sim)
        sim.commands = sim.controller.command(sim.state)
        sim.actuate(sim, sim.commands)
        for o in self.observers:
            o.before_tick(sim)
        start = time.perf_counter()
        if self.before_step or self.after_step:
            for _ in range(sim.control_every):
                for o in self.before_step:
                    o.before_physics_step(sim)
                mujoco.mj_step(sim.model, data)
                for o in self.after_step:
                    o.after_physics_step(sim)
        else:
            mujoco.mj_step(sim.model, data, nstep=sim.control_every)
        self.physics_seconds += time.perf_counter() - start
        self.ticks += 1
        for o in self.observers:
            failure = o.after_tick(sim)
            if failure is not None:
                return failure
        return None

    def close(self) -> None:
        for o in self.observers:
            o.close(self.sim)


def simulate(sim: Simulation, n_ticks: int, observers: Sequence[Observer] = ()) -> SimResult:
    """Prime the controller, then run ``n_ticks`` control ticks (see the module docstring)."""
    loop: TickLoop | None = None
    failure: str | None = None
    try:
        loop = TickLoop(sim, observers)
        for _ in range(n_ticks):
            failure = loop.tick()
            if failure is not None:
                break
    finally:
        if loop is not None:
            loop.close()
        else:
            for o in observers:
                o.close(sim)
    return SimResult(loop.ticks if loop is not None else 0, failure, loop.physics_seconds if loop is not None else 0.0)


# ------------------------------------------------------------------ built-in observers
class HealthCheck(Observer):
    """Stops the run on a new MuJoCo warning or a non-finite state."""

    def start(self, sim: Simulation) -> None:
        self.baseline = sim.data.warning.number.copy()

    def after_tick(self, sim: Simulation) -> str | None:
        data = sim.data
        grew = np.flatnonzero(data.warning.number > self.baseline)
        if grew.size:
            return f"MuJoCo warning {mujoco.mjtWarning(int(grew[0])).name} at t = {data.time:.4f} s"
        if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
            return f"non-finite state at t = {data.time:.4f} s"
        return None


class CutterObserver(Observer):
    """The foam cutter (``model.cutting.CuttingObserver``): cutting force and spindle loop before
    every physics step, connectivity after each tick, its own record every ``every`` ticks."""

    def __init__(self, sim: Simulation, every: int = 1) -> None:
        from ..model.cutting import CuttingObserver

        config = sim.context.config
        self.cutting = CuttingObserver(sim, config.layout, config.scene, every)
        self.cutter = self.cutting.cutter

    def before_tick(self, sim: Simulation) -> None:
        self.cutting.before_tick(sim)

    def before_physics_step(self, sim: Simulation) -> None:
        self.cutting.before_physics_step(sim)

    def after_tick(self, sim: Simulation) -> str | None:
        return self.cutting.after_tick(sim)


class Recorder(Observer):
    """One row of every series per ``every``-th tick, read before the tick's physics steps."""

    def __init__(self, every: int, cutter: CutterObserver) -> None:
        self.every = max(1, int(every))
        self.cutter = cutter.cutter
        self.rows: dict[str, list[Any]] = {}

    def _add(self, key: str, value: Any) -> None:
        self.rows.setdefault(key, []).append(np.array(value, copy=True))

    def before_tick(self, sim: Simulation) -> None:
        if sim.tick % self.every:
            return
        data, h, plan, i = sim.data, sim.handles, sim.plan, sim.plan_index
        commands = sim.commands
        add = self._add
        add("t", data.time)
        add("stage", plan.stage[i])
        add("plan_index", i)
        for arm in h.arms:
            site = h.tcp_site[arm]
            n_sections = len(h.cable_actuators[arm]) // 3
            add(f"{arm}_q_plan", plan.q(arm)[i])
            bending = None if commands is None else commands.bending.get(arm)
            add(f"{arm}_w_cmd", np.full(2 * n_sections, np.nan) if bending is None else bending)
            add(f"{arm}_tcp_plan", plan.tcp(arm)[i])
            add(f"{arm}_tcp_pos", data.site_xpos[site])
            add(f"{arm}_tcp_mat", data.site_xmat[site].reshape(3, 3))
            add(f"{arm}_cable_length", data.ten_length[h.cable_tendons[arm]])
            add(f"{arm}_cable_tension", -data.actuator_force[h.cable_actuators[arm]])
            common = None if commands is None else commands.common_mode.get(arm)
            add(f"{arm}_cable_common_mode", np.full(n_sections, np.nan) if common is None else common)
            add(f"{arm}_disk_pos", data.xpos[h.disk_bodies[arm]])
        add("sample_pos", data.xpos[h.sample_body])
        R = data.xmat[h.plate_body].reshape(3, 3)
        add("sample_rel_pos", R.T @ (data.xpos[h.sample_body] - data.xpos[h.plate_body]))
        add("sample_welded", bool(data.eq_active[h.sample_weld]))
        add("cells_remaining", self.cutter.cells_remaining)
        add("spindle_speed", data.qvel[h.spindle_dof])
        add("contact_force", contact_forces(sim.model, data, h.geom_kind))

    def arrays(self) -> dict[str, np.ndarray]:
        return {key: np.stack(rows) for key, rows in self.rows.items()}


class VideoObserver(Observer):
    """Streams frames into ``video.mp4`` at the configured rate of simulated time."""

    def __init__(self, sim: Simulation, path: Any, simulation_config: Any, model: Any = None) -> None:
        """``model``: the model to draw (default ``sim.model``; the spatial twin of a native-cable model)."""
        from ..video import VideoRecorder

        c = simulation_config
        self.render_model = sim.model if model is None else model
        self.video = VideoRecorder(self.render_model, path, c.cameras, c.video_width, c.video_height, c.video_fps,
                                   shadows=c.video_shadows)

    def after_tick(self, sim: Simulation) -> str | None:
        if self.render_model is not sim.model and sim.data.time + 1e-12 >= self.video.next_time:
            self.render_model.geom_rgba[:] = sim.model.geom_rgba  # colours the run changed (cut material)
        self.video.maybe_capture(sim.data)
        return None

    def close(self, sim: Simulation) -> None:  # noqa: ARG002 - the hook's signature
        self.video.close()


class ProgressObserver(Observer):
    """A tqdm bar in simulated seconds, refreshed every 100 ticks."""

    def __init__(self, end_time: float) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=round(end_time, 2), unit="sim s", desc="scenario",
                        bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} sim s [{elapsed}<{remaining}]")

    def after_tick(self, sim: Simulation) -> str | None:
        if sim.tick % 100 == 0:
            self.bar.n = min(round(sim.data.time, 2), self.bar.total)
            self.bar.refresh()
        return None

    def close(self, sim: Simulation) -> None:
        self.bar.n = min(round(sim.data.time, 2), self.bar.total)  # the last tick may end past the plan
        self.bar.close()


# ------------------------------------------------------------------ contact forces
def contact_forces(model: mujoco.MjModel, data: mujoco.MjData, kind: np.ndarray) -> np.ndarray:
    """Normal contact force (N) summed per CONTACT_KINDS entry: cutter, gripper, arm–arm, arm–world."""
    n = data.ncon
    if n == 0:
        return np.zeros(len(CONTACT_KINDS))
    normal = normal_forces(model, data, n)
    pair = kind[data.contact.geom[:n]]
    low, high = pair.min(axis=1), pair.max(axis=1)
    cutter = (low == GeomKind.CUTTER) | (high == GeomKind.CUTTER)
    gripper = ~cutter & ((low == GeomKind.GRIPPER) | (high == GeomKind.GRIPPER))
    arm_arm = (low == GeomKind.FIRST_ARM) & (high == GeomKind.SECOND_ARM)
    arm_world = (low == GeomKind.OTHER) & ((high == GeomKind.FIRST_ARM) | (high == GeomKind.SECOND_ARM))
    return np.array([normal[mask].sum() for mask in (cutter, gripper, arm_arm, arm_world)])


def normal_forces(model: mujoco.MjModel, data: mujoco.MjData, n: int) -> np.ndarray:
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
