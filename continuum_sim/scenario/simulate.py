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

import math
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
    # The model to draw (same state layout as ``model``): the spatial twin of a native-cable
    # model, whose fixed-tendon cables MuJoCo does not draw (model.cable_path); None: ``model``.
    render_model: mujoco.MjModel | None = None
    # The foam cutter (``plant.cutter.FoamCutter``: its voxel grid, cut progress, spindle), set
    # by the runner for observers that show it (the video); None: a run without one.
    cutter: Any = None

    @property
    def drawable_model(self) -> mujoco.MjModel:
        return self.model if self.render_model is None else self.render_model

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
    """Stops the run on a new MuJoCo warning or a non-finite state.

    One compiled pass (``_health_code``) over the warning counters, ``qpos`` and ``qvel``
    per tick; the message is built as before only when it finds something.
    """

    def start(self, sim: Simulation) -> None:
        self.baseline = sim.data.warning.number.copy()
        self._data: mujoco.MjData | None = None
        self._arrays: tuple[np.ndarray, ...] = ()

    def after_tick(self, sim: Simulation) -> str | None:
        data = sim.data
        if data is not self._data:  # the views stay valid as long as ``data`` does
            self._data, self._arrays = data, (data.warning.number, data.qpos, data.qvel)
        number, qpos, qvel = self._arrays
        code = _kernels()[1](number, self.baseline, qpos, qvel)
        if code == _WARNED:
            grew = np.flatnonzero(number > self.baseline)
            return f"MuJoCo warning {mujoco.mjtWarning(int(grew[0])).name} at t = {data.time:.4f} s"
        if code == _NOT_FINITE:
            return f"non-finite state at t = {data.time:.4f} s"
        return None


_HEALTHY, _WARNED, _NOT_FINITE = 0, 1, 2


def _health_code(number: np.ndarray, baseline: np.ndarray, qpos: np.ndarray, qvel: np.ndarray) -> int:  # pragma: no cover - numba
    """_WARNED if a warning counter grew past ``baseline``, else _NOT_FINITE if ``qpos`` or
    ``qvel`` holds a NaN or an infinity, else _HEALTHY."""
    for i in range(number.shape[0]):
        if number[i] > baseline[i]:
            return _WARNED
    for x in qpos:
        if not math.isfinite(x):
            return _NOT_FINITE
    for x in qvel:
        if not math.isfinite(x):
            return _NOT_FINITE
    return _HEALTHY


class CutterObserver(Observer):
    """The foam cutter (``plant.cut_record.CuttingObserver``): spindle loop and cutting force before
    every physics step, connectivity after each tick, its own record every ``every`` ticks."""

    def __init__(self, sim: Simulation, every: int = 1) -> None:
        from ..plant.cut_record import CuttingObserver

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
    """One row of every series per ``every``-th tick, read before the tick's physics steps.

    Each row is written in place into preallocated arrays (row shape and dtype those of the
    first row's values, doubled when full): a list of copies per value and a final
    ``np.stack`` cost a Python call and an allocation each. The rows keep whole copies of
    ``data.xpos``, the tool sites' ``site_xpos``/``site_xmat``, ``ten_length`` and ``actuator_force`` (a
    memcpy each) and the plan index; ``arrays`` picks the series out of those afterwards,
    the same values as picking them per row.
    """

    _KEYS = ("t", "plan_index", "xpos", "site_xpos", "site_xmat", "ten_length", "actuator_force")
    _TAIL = ("sample_rel_pos", "sample_welded", "cells_remaining", "spindle_speed", "contact_force")

    def __init__(self, every: int, cutter: CutterObserver) -> None:
        self.every = max(1, int(every))
        self.cutter = cutter.cutter
        self.n = 0  # rows recorded
        self.keys: list[str] = []
        self.columns: list[np.ndarray] = []
        self.plan: TaskPlan | None = None
        self.handles: SceneHandles | None = None
        self._tcp_sites = np.zeros(0, dtype=int)

    def _allocate(self, sim: Simulation, values: list[Any]) -> None:
        """Name the first row's ``values`` (in ``before_tick``'s order) and allocate their arrays."""
        self.keys = [*self._KEYS, *(f"{arm}_{name}" for arm in sim.handles.arms for name in ("w_cmd", "cable_common_mode")),
                     *self._TAIL]
        firsts = [np.asarray(value) for value in values]
        self.columns = [np.empty((256, *first.shape), dtype=first.dtype) for first in firsts]
        self.plan, self.handles = sim.plan, sim.handles
        self._tcp_sites = np.array([sim.handles.tcp_site[arm] for arm in sim.handles.arms])

    def before_tick(self, sim: Simulation) -> None:
        if sim.tick % self.every:
            return
        data, h, commands = sim.data, sim.handles, sim.commands
        xpos = data.xpos
        tcp = self._tcp_sites if self.columns else np.array([h.tcp_site[arm] for arm in h.arms])
        # Only the tool sites: a native-cable arm also has ~380 hole sites (28 kB of site_xmat per row).
        values: list[Any] = [data.time, sim.plan_index, xpos, data.site_xpos[tcp], data.site_xmat[tcp],
                             data.ten_length, data.actuator_force]
        for arm in h.arms:
            n_sections = len(h.cable_actuators[arm]) // 3
            bending = None if commands is None else commands.bending.get(arm)
            common = None if commands is None else commands.common_mode.get(arm)
            values.append(np.full(2 * n_sections, np.nan) if bending is None else bending)
            values.append(np.full(n_sections, np.nan) if common is None else common)
        R = data.xmat[h.plate_body].reshape(3, 3)
        values += (R.T @ (xpos[h.sample_body] - xpos[h.plate_body]), bool(data.eq_active[h.sample_weld]),
                   self.cutter.cells_remaining, data.qvel[h.spindle_dof], contact_forces(sim.model, data, h.geom_kind))
        if not self.columns:
            self._allocate(sim, values)
        elif sim.plan is not self.plan or h is not self.handles:
            raise RuntimeError("Recorder: the simulation's plan or handles changed during the run")
        n, columns = self.n, self.columns
        if n == len(columns[0]):
            self.columns = columns = [np.concatenate([c, np.empty_like(c)]) for c in columns]
        for column, value in zip(columns, values, strict=True):
            column[n] = value
        self.n = n + 1

    def arrays(self) -> dict[str, np.ndarray]:
        """Every series, (rows, ...) each; none before the first row."""
        if not self.n:
            return {}
        rows = {key: column[: self.n] for key, column in zip(self.keys, self.columns, strict=True)}
        plan, h = self.plan, self.handles
        assert plan is not None and h is not None
        index = rows["plan_index"]
        xpos = rows["xpos"]
        out = {"t": rows["t"].copy(), "stage": plan.stage[index], "plan_index": index.copy()}
        for column, arm in enumerate(h.arms):  # the tool sites were recorded in the arms' order
            out |= {
                f"{arm}_q_plan": plan.q(arm)[index],
                f"{arm}_w_cmd": rows[f"{arm}_w_cmd"].copy(),
                f"{arm}_tcp_plan": plan.tcp(arm)[index],
                f"{arm}_tcp_pos": rows["site_xpos"][:, column],
                f"{arm}_tcp_mat": rows["site_xmat"][:, column].reshape(self.n, 3, 3),
                f"{arm}_cable_length": rows["ten_length"][:, h.cable_tendons[arm]],
                f"{arm}_cable_tension": -rows["actuator_force"][:, h.cable_actuators[arm]],
                f"{arm}_cable_common_mode": rows[f"{arm}_cable_common_mode"].copy(),
                f"{arm}_disk_pos": xpos[:, h.disk_bodies[arm]],
            }
        out["sample_pos"] = xpos[:, h.sample_body]
        return out | {key: rows[key].copy() for key in self._TAIL}


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
    """Normal contact force (N) summed per CONTACT_KINDS entry: cutter, gripper, arm–arm, arm–world.

    One compiled pass (``_contact_sums``) sorts the contacts and sums each kind's forces
    as ``normal[mask].sum()`` did (numpy's pairwise order, so bit-identical).
    """
    n = data.ncon
    if n == 0:
        return np.zeros(len(CONTACT_KINDS))
    contact = data.contact
    out = np.zeros(len(CONTACT_KINDS))
    if data.nefc == 0:
        return out  # every normal force is zero (as normal_forces gives), and so is each sum
    if model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC:
        _kernels()[0](contact.geom, contact.efc_address, data.efc_force, _NO_FORCES, kind, n, out)
    else:
        _kernels()[0](contact.geom, contact.efc_address, data.efc_force, normal_forces(model, data, n), kind, n, out)
    return out


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


_OTHER, _CUTTER, _GRIPPER = int(GeomKind.OTHER), int(GeomKind.CUTTER), int(GeomKind.GRIPPER)
_FIRST_ARM, _SECOND_ARM = int(GeomKind.FIRST_ARM), int(GeomKind.SECOND_ARM)
_NO_FORCES = np.zeros(0)  # ``_contact_sums``'s ``normal`` for elliptic cones: it reads efc_force itself


def _block_sum(a: np.ndarray, start: int, n: int) -> float:  # pragma: no cover - numba
    """numpy's float64 pairwise_sum of ``a[start:start + n]`` for n ≤ 128: sequential below 8,
    else 8 accumulators over the whole multiples of 8 and the rest added in order."""
    if n < 8:
        res = 0.0
        for i in range(start, start + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[start], a[start + 1], a[start + 2], a[start + 3]
    r4, r5, r6, r7 = a[start + 4], a[start + 5], a[start + 6], a[start + 7]
    i = 8
    whole = n - n % 8
    while i < whole:
        j = start + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[start + i]
        i += 1
    return res


def _pairwise_sum(a: np.ndarray, n: int) -> float:  # pragma: no cover - numba
    """numpy's float64 ``add.reduce`` of ``a[:n]``, in its order: 0.0 + pairwise_sum, which halves
    a range of over 128 (the first half a multiple of 8) and adds the halves' sums.

    The recursion is unrolled onto an explicit stack (numba's on-disk cache crashed loading
    the recursive version).
    """
    if n <= 128:
        return 0.0 + _block_sum(a, 0, n)
    starts = np.empty(64, dtype=np.int64)
    sizes = np.empty(64, dtype=np.int64)
    phase = np.zeros(64, dtype=np.int64)  # 0: split next, 1: right half next, 2: add the halves
    sums = np.empty(64)
    top, n_sums = 0, 0
    starts[0], sizes[0], phase[0] = 0, n, 0
    while top >= 0:
        start, size = starts[top], sizes[top]
        half = size // 2
        half -= half % 8
        if size <= 128:
            sums[n_sums] = _block_sum(a, start, size)
            n_sums += 1
            top -= 1
        elif phase[top] == 0:
            phase[top] = 1
            top += 1
            starts[top], sizes[top], phase[top] = start, half, 0
        elif phase[top] == 1:
            phase[top] = 2
            top += 1
            starts[top], sizes[top], phase[top] = start + half, size - half, 0
        else:
            n_sums -= 1
            sums[n_sums - 1] = sums[n_sums - 1] + sums[n_sums]
            top -= 1
    return 0.0 + sums[0]


def _contact_sums(geom: np.ndarray, address: np.ndarray, efc_force: np.ndarray, normal: np.ndarray, kind: np.ndarray,
                  n: int, out: np.ndarray) -> None:  # pragma: no cover - numba
    """``out[k]`` = the summed normal force of the first ``n`` contacts of CONTACT_KINDS entry k.

    ``normal``: the contacts' normal forces, or empty to read them from ``efc_force`` at the
    contacts' first constraint row (elliptic cones; 0 for a contact without rows).
    """
    picked = np.empty((4, n))
    count = np.zeros(4, dtype=np.int64)
    for i in range(n):
        if normal.shape[0] == 0:
            row = address[i]
            force = abs(efc_force[max(row, 0)]) if row >= 0 else 0.0
        else:
            force = normal[i]
        a, b = kind[geom[i, 0]], kind[geom[i, 1]]
        low, high = min(a, b), max(a, b)
        # The kinds are exclusive, in the order of CONTACT_KINDS (a cutter contact is never a gripper one).
        if low == _CUTTER or high == _CUTTER:
            k = 0
        elif low == _GRIPPER or high == _GRIPPER:
            k = 1
        elif low == _FIRST_ARM and high == _SECOND_ARM:
            k = 2
        elif low == _OTHER and (high == _FIRST_ARM or high == _SECOND_ARM):
            k = 3
        else:
            continue
        picked[k, count[k]] = force
        count[k] += 1
    for k in range(4):
        out[k] = _pairwise_sum(picked[k], count[k])


_KERNELS: list[Any] = []


def _kernels() -> list[Any]:
    """[``_contact_sums``, ``_health_code``] compiled by numba (or loaded from its cache) on first use."""
    if not _KERNELS:
        from ..plant.jit import jit_in_place, sigint_deferred

        with sigint_deferred():
            jit_in_place(globals(), ("_block_sum", "_pairwise_sum", "_contact_sums", "_health_code"))
            _KERNELS.extend((_contact_sums, _health_code))
    return _KERNELS
