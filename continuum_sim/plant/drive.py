"""The drives between the controller's commands and the actuators: cable motors, gripper motor, spindle.

Motor. A geared DC motor with an encoder position loop (the prototype's 19 closed-loop
motor units; SPEC §6a, docs/plant.md). Its speed follows the DC motor's torque–speed line:
the loop's voltage command sets a no-load speed v_cmd (saturated at ±v_max, the speed
limit) and the cable's load slows the reel-in by droop·T with droop = v_max/Fmax, so at
full command the motor stalls exactly at the force limit Fmax (= torque / spool radius)
and a larger pull back-drives it. A proportional loop therefore leaves a steady error
droop·T/kp under load; the integral term removes it. A velocity feed-forward of the
set-point's rate makes ramps track without lag. The cable is the elastic spring of
``model.cable_elasticity``: its stiffness EA/(lead + tendon length) is written into the
actuator every tick, with the spring's backward-Euler term on taut cables only.

The motor state is advanced once per control tick, implicitly (backward Euler in the
motor position, the integrator and the cable's droop term), so the update is stable for
any tick length and cable stiffness; within a tick MuJoCo holds the motor position (the
tick's mean). Adequacy: with kp = 40 1/s the loop's bandwidth is ≈ 6 Hz (critically damped
PI, ki = kp²/4 ⇒ double pole at kp/2 = 20 rad/s → 3 Hz per pole), above the arm's first
bending modes (≈ 1–2 Hz) and below the 125 Hz tick, and the feed-forward takes the ramps.

``drive_motors`` (compiled) is the one implementation of a tick; ``MotorBank.command`` runs
it on one bank, ``MotorDrive`` on every bank at once.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..geometry import ArmGeometry
from ..model.cable_elasticity import implicit_spring_step, rope_axial_stiffness
from ..model.options import ModelOptions
from .jit import jit
from .spindle import SpindleDrive

Array = NDArray[np.float64]

# Rows of the per-motor constants (``drive_motors``'s ``const``).
EA, LEAD, VG, H, DROOP, KP, KI, VMAX = range(8)
N_CONST = 8


@jit
def drive_motors(state: np.ndarray, s: np.ndarray, ten_length: np.ndarray, ctrl: np.ndarray, gainprm: np.ndarray,
                 biasprm: np.ndarray, index: np.ndarray, const: np.ndarray, nc: int, dt: float) -> None:
    """One tick of ``dt`` of motors toward the set-points ``s``: the cables' stiffness write (the
    first ``nc`` motors: spring k = EA/(lead + l) as gain and length bias, velocity gain
    VG + k·h on taut cables) and the PI loop; ``dt`` <= 0: the stiffness write and the motor
    positions as controls only. ``state`` rows: position, integral, set-point (updated in
    place); ``index`` rows: actuator, tendon; ``const`` rows: ``EA`` … ``VMAX``."""
    for i in range(s.shape[0]):
        act = index[0, i]
        x = state[0, i]
        integral = state[1, i]
        s_i = s[i]
        length = ten_length[index[1, i]]
        h = const[H, i]
        k = const[EA, i] / (const[LEAD, i] + length) if i < nc else gainprm[act, 0]
        taut = length > x  # the cable pulls on the motor: its droop term acts
        if i < nc:
            gainprm[act, 0] = k
            biasprm[act, 1] = -k
            biasprm[act, 2] = -(const[VG, i] + (k * h if taut else 0.0))
        if dt <= 0.0:
            ctrl[act] = x
            continue
        droop, kp, ki, vmax = const[DROOP, i], const[KP, i], const[KI, i], const[VMAX, i]
        v_ff = (s_i - state[2, i]) / dt
        dk = droop * k if taut else 0.0
        # Backward Euler in (x, ∫e): x' = x + dt·(v_cmd + droop·k·(l − x')),
        # v_cmd = v_ff + kp·(s − x') + ki·(∫e + dt·(s − x')).
        a = kp + ki * dt
        x_new = (x + dt * (v_ff + a * s_i + ki * integral + dk * length)) / (1.0 + dt * (a + dk))
        v_cmd = v_ff + a * (s_i - x_new) + ki * integral
        if abs(v_cmd) > vmax:
            # Voltage at its limit: the command is ±v_max and the integrator holds (anti-windup).
            v_sat = min(max(v_cmd, -vmax), vmax)
            x_new = (x + dt * (v_sat + dk * length)) / (1.0 + dt * dk)
        else:
            integral = integral + dt * (s_i - x_new)
        # Backward Euler on the spring uses the motor's position at the end of the step,
        # x + h·ẋ: with the velocity term −k·h·l̇ the implicit part acts on the stretch rate
        # ẋ − l̇ only, so a cable that follows its motor is not dragged.
        ctrl[act] = 0.5 * (x + x_new) + h * (x_new - x) / dt
        state[0, i] = x_new
        state[1, i] = integral
        state[2, i] = s_i


@dataclass(frozen=True)
class MotorRatings:
    """One motor's loop and limits, at the cable (m, m/s, N)."""

    max_speed: float
    max_force: float
    kp: float
    ki: float

    @property
    def droop(self) -> float:
        """Speed lost per newton of cable load (m/s/N): the torque–speed line through v_max and Fmax."""
        return self.max_speed / self.max_force


def arm_motor_ratings(options: ModelOptions) -> MotorRatings:
    return MotorRatings(options.motor_max_speed, options.cable_max_force, options.motor_kp, options.motor_ki)


class MotorBank:
    """The motors of a set of cable actuators: motor positions, PI state, limits.

    ``actuators``/``tendons``: model indices of the cables' actuators and tendons.
    ``stiffness_ea``: E·A per cable (N) and ``lead``: lead length per cable (m) for the
    elastic model — the stiffness is re-evaluated every tick from the current routed
    length (lead + tendon length); None keeps the model's own (lumped) gain.
    ``ideal``: the lumped legacy model — the set-point goes to the actuator unchanged.
    ``velocity_gain`` (N·s/m, the motor loop's cable_kv) and ``implicit_step`` (s, h of the
    spring's backward-Euler term, ``cable_velocity_gain``): the actuators' velocity gain is
    set every tick to velocity_gain + k·h on taut cables and velocity_gain on slack ones.
    """

    def __init__(self, model: Any, actuators: Any, tendons: Any, ratings: MotorRatings, stiffness_ea: Any = None,
                 lead: Any = None, ideal: bool = False, velocity_gain: float = 0.0, implicit_step: float = 0.0) -> None:
        self.model = model
        self.actuators = np.asarray(actuators, dtype=int)
        self.tendons = np.asarray(tendons, dtype=int)
        self.ratings = ratings
        n = len(self.actuators)
        self.ea = None if stiffness_ea is None else np.broadcast_to(np.asarray(stiffness_ea, float), (n,)).copy()
        self.lead = None if lead is None else np.broadcast_to(np.asarray(lead, float), (n,)).copy()
        self.ideal = bool(ideal)
        self.velocity_gain = float(velocity_gain)
        self.implicit_step = float(implicit_step)
        self.position = np.zeros(n)  # motor positions along the cable (m)
        self.integral = np.zeros(n)  # ∫ error dt (m·s)
        self.set_point = np.zeros(n)
        self._started = False
        self.elastic = self.ea is not None and self.lead is not None
        self.const = np.zeros((N_CONST, n))
        if self.elastic:
            self.const[EA], self.const[LEAD] = self.ea, self.lead
        self.const[VG], self.const[H] = self.velocity_gain, self.implicit_step
        self.const[DROOP], self.const[KP], self.const[KI] = ratings.droop, ratings.kp, ratings.ki
        self.const[VMAX] = ratings.max_speed
        self.index = np.stack([self.actuators, self.tendons]).astype(np.int64)

    def stiffness(self, data: Any) -> Array:
        """Current cable stiffness (N/m) per motor: EA / (lead + tendon length), or the model's gain."""
        if self.ea is None or self.lead is None:
            return self.model.actuator_gainprm[self.actuators, 0].copy()
        return self.ea / (self.lead + data.ten_length[self.tendons])

    def tensions(self, data: Any) -> Array:
        """Measured cable tensions (N, ≥ 0) from the actuators' forces."""
        return -data.actuator_force[self.actuators]

    def reset(self, data: Any, set_points: Any) -> None:
        """Motors at their set-points with the integrators empty (the run's first tick)."""
        self.set_point = np.asarray(set_points, dtype=float).copy()
        self.position = self.set_point.copy()
        self.integral = np.zeros(len(self.actuators))
        self._started = True
        self._run(data, self.set_point, 0.0)

    def _run(self, data: Any, s: Array, dt: float) -> None:
        """``drive_motors`` on this bank's motors (their state gathered and put back)."""
        state = np.stack([self.position, self.integral, self.set_point])
        drive_motors(state, np.ascontiguousarray(s, dtype=float), data.ten_length, data.ctrl, self.model.actuator_gainprm,
                     self.model.actuator_biasprm, self.index, self.const, len(self.actuators) if self.elastic else 0, dt)
        self.position, self.integral, self.set_point = state[0].copy(), state[1].copy(), state[2].copy()

    def command(self, data: Any, set_points: Any, dt: float) -> None:
        """Advance every motor by one tick of ``dt`` toward ``set_points`` and write the actuators' controls."""
        s = np.asarray(set_points, dtype=float)
        if not self._started:
            self.reset(data, s)
        if dt <= 0.0:
            self.set_point = s.copy()
            data.ctrl[self.actuators] = self.position
            return
        if self.ideal:
            # The set-point is the motor position; its rate leads it by h (see ``drive_motors``).
            data.ctrl[self.actuators] = s + self.implicit_step * (s - self.set_point) / dt
            self.set_point = s.copy()
            self.position = s.copy()
            return
        self._run(data, s, dt)


def arm_motor_bank(model: Any, actuators: Any, tendons: Any, options: ModelOptions) -> MotorBank:
    """The motors of one arm's cables, as configured (elastic or lumped)."""
    n = len(actuators)
    if options.cable_model == "lumped":
        return MotorBank(model, actuators, tendons, arm_motor_ratings(options), ideal=True,
                         implicit_step=implicit_spring_step(options))
    ea = np.full(n, rope_axial_stiffness(options))
    lead = np.full(n, options.cable_lead_length)
    return MotorBank(model, actuators, tendons, arm_motor_ratings(options), stiffness_ea=ea, lead=lead,
                     velocity_gain=options.cable_kv, implicit_step=implicit_spring_step(options))


class MotorDrive:
    """The run's actuation (``scenario.simulate.Simulation.actuate``): every arm's cable lengths
    and the gripper cable through their motor banks (elastic: one ``drive_motors`` call for
    all of them; lumped: straight to the actuators), the spindle speed to the spindle drive
    (``spindle``, the one writer of the spindle's ctrl)."""

    def __init__(self, model: Any, handles: Any, geometry: ArmGeometry, options: ModelOptions, tools: Any) -> None:
        for arm in handles.arms:
            if len(handles.cable_actuators[arm]) != 3 * geometry.n_sections:
                raise ValueError(f"{arm}: {len(handles.cable_actuators[arm])} cable actuators for {geometry.n_sections} sections")
        self.banks = {
            arm: arm_motor_bank(model, handles.cable_actuators[arm], handles.cable_tendons[arm], options)
            for arm in handles.arms
        }
        grip = int(handles.gripper_actuator)
        ratings = MotorRatings(tools.gripper_cable_speed, tools.gripper_max_force, options.motor_kp, options.motor_ki)
        self.gripper = MotorBank(model, [grip], [int(model.actuator_trnid[grip, 0])], ratings,
                                 ideal=options.cable_model == "lumped")
        self.spindle = SpindleDrive(model, tools, handles.tool_arm.get("grinder", "left"))
        self.model = model
        self.fused = options.cable_model != "lumped"
        all_banks = [*self.banks.values(), self.gripper]
        self._bounds = np.cumsum([0] + [len(b.actuators) for b in all_banks])
        self._nc = int(self._bounds[-2])  # the arms' cables (elastic); the gripper's gain is the model's
        self._index = np.concatenate([b.index for b in all_banks], axis=1)
        self._const = np.concatenate([b.const for b in all_banks], axis=1)
        self._state = np.zeros((3, int(self._bounds[-1])))
        self._s = np.zeros(int(self._bounds[-1]))
        self._slices = [slice(int(a), int(b)) for a, b in itertools.pairwise(self._bounds)]
        self._views: list[tuple[Array, Array, Array]] | None = None  # the banks' state as views into ``_state``
        self._data: Any = None  # the MjData whose arrays ``_arrays`` holds
        self._arrays: tuple[Any, ...] = ()

    def __call__(self, sim: Any, commands: Any) -> None:
        dt = 0.0 if sim.tick < 0 else sim.control_period
        data = sim.data
        banks = [*self.banks.values(), self.gripper]
        if self.fused and dt > 0.0 and all(b._started for b in banks):
            self._fused_command(data, commands, banks, dt)
        else:
            for arm, bank in self.banks.items():
                bank.command(data, commands.cable_lengths[arm], dt)
            self.gripper.command(data, np.array([commands.gripper_cable], dtype=float), dt)
        self.spindle.command(data, commands.spindle_speed)

    def _fused_command(self, data: Any, commands: Any, banks: list[MotorBank], dt: float) -> None:
        """``MotorBank.command`` of every bank in one kernel call (elastic model, dt > 0, banks started).

        The motors' state lives in one (3, n) array updated in place; each bank's ``position``,
        ``integral`` and ``set_point`` are views of its columns. A bank whose attributes were
        replaced since (its own ``command``/``reset``) is gathered anew."""
        state, s, slices = self._state, self._s, self._slices
        views = self._views
        if views is None or any(b.position is not v[0] or b.integral is not v[1] or b.set_point is not v[2]
                                for b, v in zip(banks, views, strict=True)):
            for bank, sl in zip(banks, slices, strict=True):
                state[0, sl], state[1, sl], state[2, sl] = bank.position, bank.integral, bank.set_point
                bank.position, bank.integral, bank.set_point = state[0, sl], state[1, sl], state[2, sl]
            self._views = [(b.position, b.integral, b.set_point) for b in banks]
        for arm, sl in zip(self.banks, slices, strict=False):
            s[sl] = commands.cable_lengths[arm]
        s[-1] = commands.gripper_cable
        if data is not self._data:  # (each ``data.<field>`` access builds a new array object)
            self._data = data
            self._arrays = (data.ten_length, data.ctrl, self.model.actuator_gainprm, self.model.actuator_biasprm)
        drive_motors(state, s, *self._arrays, self._index, self._const, self._nc, dt)
