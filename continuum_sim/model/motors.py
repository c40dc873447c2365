"""The transmission: elastic cables and the motors' encoder loops (SPEC §6a, docs/plant.md).

Cable. Each cable is a steel wire rope of effective modulus E (on its nominal area
A = π d²/4) and routed length L = lead + in-arm path (spool → pack guides → base plate →
holes → anchor disk). It is a spring of stiffness k = E·A/L that only pulls. In the
MuJoCo model it is the cable's tension-only position actuator: force = k·(x − l),
clipped to [−Fmax, 0], with l the tendon (in-arm path) length and x the actuator's
control, the *motor position*: the length of in-arm path at which the cable would just
be taut, i.e. the motor's encoder reading expressed along the cable. So the cable's
stretch is l − x and its tension T = k·(l − x) when positive.

Motor. A geared DC motor with an encoder position loop (the prototype's 19 closed-loop
motor units). Its speed follows the DC motor's torque–speed line: the loop's voltage
command sets a no-load speed v_cmd (saturated at ±v_max, the speed limit) and the cable's
load slows the reel-in by droop·T with droop = v_max/Fmax, so at full command the motor
stalls exactly at the force limit Fmax (= torque / spool radius) and a larger pull
back-drives it. A proportional loop therefore leaves a steady error droop·T/kp under
load; the integral term removes it (the encoder loop reaches its set-point under a
steady load). A velocity feed-forward of the set-point's rate makes ramps track
without lag.

The motor state is advanced once per control tick (``MotorBank.command``), implicitly
(backward Euler in the motor position, the integrator and the cable's droop term), so
the update is stable for any tick length and cable stiffness; within a tick MuJoCo
holds the motor position (the tick's mean), exactly as it held the legacy set-points.
Adequacy: with kp = 40 1/s the loop's bandwidth is ≈ 6 Hz (critically damped PI,
ki = kp²/4 ⇒ double pole at kp/2 = 20 rad/s → 3 Hz per pole), above the arm's first
bending modes (≈ 1–2 Hz) and below the 125 Hz tick, and the feed-forward takes the
ramps; a finer motor loop would only sharpen a response the arm cannot follow.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..geometry import ArmGeometry
from ..kinematics import straight_cable_lengths
from .options import ModelOptions, model_geometry

Array = NDArray[np.float64]


def rope_area(options: ModelOptions) -> float:
    """Nominal area π d²/4 (m²) of the rope: the area the effective modulus is quoted on."""
    return math.pi * options.rope_diameter**2 / 4.0


def rope_axial_stiffness(options: ModelOptions) -> float:
    """E·A (N) of the rope."""
    return options.rope_modulus * rope_area(options)


def routed_lengths(geometry: ArmGeometry, options: ModelOptions, in_arm: Array | None = None) -> Array:
    """(n_cables,) length of rope between spool and anchor: lead + in-arm path (straight arm by default)."""
    if in_arm is None:
        in_arm = straight_cable_lengths(model_geometry(geometry, options))
    return options.cable_lead_length + np.asarray(in_arm, dtype=float)


def cable_stiffness(geometry: ArmGeometry, options: ModelOptions, in_arm: Array | None = None) -> Array:
    """(n_cables,) axial stiffness (N/m) of every cable: EA/L, or the lumped cable_kp.

    Distal cables run through the proximal sections as well, so they are longer and softer.
    """
    n = 3 * geometry.n_sections
    if options.cable_model == "lumped":
        return np.full(n, float(options.cable_kp))
    return rope_axial_stiffness(options) / routed_lengths(geometry, options, in_arm)


# N·s²/m: the largest k·h² of an arm's stiffest cable verified to run the whole default task
# (rope d = 2.08 mm: proximal cables 5.4e5 N/m at the 4 ms step, the task completes or fails
# by name); d = 2.6 mm (8.5e5 N/m, k·h² = 13.5) and 3.7 mm (1.7e6 N/m) diverged at 4 ms and
# run at 2 ms (docs/plant.md, "Cable stiffness 1e4–1e6 N/m"). The shipped rope: 2.0.
CABLE_STEP_LIMIT = 8.6


# N·m·s²/rad: the largest k·h² of the stiffest flexure joint verified to run the whole default
# task (hinges ×8 at 4 ms: 91.9 N·m/rad, 1.47e-3); ×11.3 (130 N·m/rad, 2.1e-3) diverged at 4 ms
# in the task and in the static sag evaluation, ×16 runs at 2 ms (named failure, not divergence).
# Joint springs are explicit under implicitfast, as the cable spring was (docs/plant.md).
JOINT_STEP_LIMIT = 1.5e-3


def stiffest_joint(geometry: ArmGeometry, options: ModelOptions) -> float:
    """The largest flexure-joint spring (N·m/rad) of the model (0 for the rod backbone)."""
    from .stiffness import joint_stiffnesses

    if geometry.backbone == "rod":
        return 0.0
    model_geom = model_geometry(geometry, options)
    largest = 0.0
    for index, section in enumerate(model_geom.sections):
        kx, ky, kz = joint_stiffnesses(geometry, index, section.n_segments, options.stiffness_scale)
        twist = kz if options.joint == "hinge_triple" and math.isfinite(kz) else 0.0
        largest = max(largest, kx, ky, twist)
    return largest


def stable_timestep(geometry: ArmGeometry, options: ModelOptions) -> float:
    """The physics step (s): ``options.timestep`` divided by the smallest whole n with
    k·(h/n)² within its verified limit for the stiffest cable (EA/L or the lumped gain,
    CABLE_STEP_LIMIT) and the stiffest flexure joint (JOINT_STEP_LIMIT)."""
    h = float(options.timestep)
    if not options.stable_step:
        return h
    ratio = stiffest_joint(geometry, options) * h * h / JOINT_STEP_LIMIT
    if options.tendons:
        ratio = max(ratio, float(np.max(cable_stiffness(geometry, options))) * h * h / CABLE_STEP_LIMIT)
    n = max(1, math.ceil(math.sqrt(ratio) - 1e-9))
    return h / n


def implicit_spring_step(options: ModelOptions) -> float:
    """h (s) of the cable spring's backward-Euler velocity term k·h, or 0 when it is off."""
    return float(options.timestep) if options.cable_implicit_spring else 0.0


def cable_velocity_gain(stiffness: float, options: ModelOptions) -> float:
    """The cable actuator's velocity gain (N·s/m) while taut: the motor loop's cable_kv plus k·h.

    Backward Euler on the spring, T_{n+1} = k·(x − l_{n+1}) ≈ k·(x − l_n) − k·h·l̇_{n+1}: the
    term −k·h·l̇ is an actuator velocity bias, which MuJoCo's implicitfast integrator treats
    implicitly. It is the integrator's numerical damping of the stiff spring (it vanishes as
    h → 0), not a physical damper; without it the explicit spring k·h² exceeds what the
    distal disks' mass and the cable's damping can carry once a grasp pins the tip, and the
    4 ms step rings at ~25 Hz (docs/plant.md, "Tension chatter").
    """
    return float(options.cable_kv) + float(stiffness) * implicit_spring_step(options)


def pretension_offsets(geometry: ArmGeometry, options: ModelOptions, pretension: float) -> Array:
    """(n_cables,) motor set-point offsets (m) that give ``pretension`` at the planned shape: T/k."""
    return float(pretension) / cable_stiffness(geometry, options)


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


def _write_cable_stiffness(model, actuators: Array, k: Array, taut: Array, velocity_gain, h) -> None:
    """The cable actuators' spring k (gain and length bias) and velocity gain: velocity_gain + k·h
    on taut cables (the spring's backward-Euler term), velocity_gain on slack ones."""
    model.actuator_gainprm[actuators, 0] = k
    model.actuator_biasprm[actuators, 1] = -k
    model.actuator_biasprm[actuators, 2] = -(velocity_gain + np.where(taut, k * h, 0.0))


def _motor_step(x: Array, integral: Array, set_point: Array, s: Array, length: Array, k: Array, droop, kp, ki,
                max_speed, h, dt: float) -> tuple[Array, Array, Array]:
    """One tick of the motors' PI encoder loops: (new position, new integral, actuator control).

    Ratings may be scalars (one bank) or per-motor arrays (``MotorDrive``'s fused update):
    the same elementwise operations either way, so the results are bit-identical.
    """
    v_ff = (s - set_point) / dt
    taut = length > x  # the cable pulls on the motor: its droop term acts
    dk = np.where(taut, droop * k, 0.0)
    # Backward Euler in (x, ∫e): x' = x + dt·(v_cmd + droop·k·(l − x')),
    # v_cmd = v_ff + kp·(s − x') + ki·(∫e + dt·(s − x')).
    a = kp + ki * dt
    x_new = (x + dt * (v_ff + a * s + ki * integral + dk * length)) / (1.0 + dt * (a + dk))
    v_cmd = v_ff + a * (s - x_new) + ki * integral
    saturated = np.abs(v_cmd) > max_speed
    if np.any(saturated):
        # Voltage at its limit: the command is ±v_max and the integrator holds (anti-windup).
        v_sat = np.clip(v_cmd, -max_speed, max_speed)
        x_sat = (x + dt * (v_sat + dk * length)) / (1.0 + dt * dk)
        x_new = np.where(saturated, x_sat, x_new)
    integral = np.where(saturated, integral, integral + dt * (s - x_new))
    # Backward Euler on the spring uses the motor's position at the end of the step,
    # x + h·ẋ: with the velocity term −k·h·l̇ the implicit part acts on the stretch rate
    # ẋ − l̇ only, so a cable that follows its motor is not dragged.
    ctrl = 0.5 * (x + x_new) + h * (x_new - x) / dt
    return x_new, integral, ctrl


class MotorBank:
    """The motors of a set of cable actuators: motor positions, PI state, limits.

    ``actuators``/``tendons``: model indices of the cables' actuators and tendons.
    ``stiffness_ea``: E·A per cable (N) and ``lead``: lead length per cable (m) for the
    elastic model — the stiffness is re-evaluated every tick from the current routed
    length (lead + tendon length); None keeps the model's own (lumped) gain.
    ``ideal``: the lumped legacy model — the set-point goes to the actuator unchanged.
    ``velocity_gain`` (N·s/m, the motor loop's cable_kv) and ``implicit_step`` (s, h of the
    spring's backward-Euler term, ``cable_velocity_gain``): the actuators' velocity gain is
    set every tick to velocity_gain + k·h on taut cables and velocity_gain on slack ones
    (a slack cable carries no spring, so no spring term either).
    """

    def __init__(
        self,
        model,
        actuators: Array,
        tendons: Array,
        ratings: MotorRatings,
        stiffness_ea: Array | None = None,
        lead: Array | None = None,
        ideal: bool = False,
        velocity_gain: float = 0.0,
        implicit_step: float = 0.0,
    ) -> None:
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

    def stiffness(self, data) -> Array:
        """Current cable stiffness (N/m) per motor: EA / (lead + tendon length), or the model's gain."""
        if self.ea is None or self.lead is None:
            return self.model.actuator_gainprm[self.actuators, 0].copy()
        return self.ea / (self.lead + data.ten_length[self.tendons])

    def tensions(self, data) -> Array:
        """Measured cable tensions (N, ≥ 0) from the actuators' forces."""
        return -data.actuator_force[self.actuators]

    def reset(self, data, set_points: Array) -> None:
        """Motors at their set-points with the integrators empty (the run's first tick)."""
        self.set_point = np.asarray(set_points, dtype=float).copy()
        self.position = self.set_point.copy()
        self.integral[:] = 0.0
        self._started = True
        self._update_stiffness(data)
        data.ctrl[self.actuators] = self.position

    def _update_stiffness(self, data) -> Array:
        """Write the current cable stiffness into the actuators (elastic model); return it."""
        k = self.stiffness(data)
        if self.ea is not None and self.lead is not None:
            taut = data.ten_length[self.tendons] > self.position
            _write_cable_stiffness(self.model, self.actuators, k, taut, self.velocity_gain, self.implicit_step)
        return k

    def command(self, data, set_points: Array, dt: float) -> None:
        """Advance every motor by one tick of ``dt`` toward ``set_points`` and write the actuators' controls."""
        s = np.asarray(set_points, dtype=float)
        if not self._started or dt <= 0.0:
            self.reset(data, s) if not self._started else None
            if dt <= 0.0:
                self.set_point = s.copy()
                data.ctrl[self.actuators] = self.position
                return
        if self.ideal:
            # The set-point is the motor position; its rate leads it by h (see below).
            data.ctrl[self.actuators] = s + self.implicit_step * (s - self.set_point) / dt
            self.set_point = s.copy()
            self.position = s.copy()
            return
        k = self._update_stiffness(data)
        r = self.ratings
        x_new, integral, ctrl = _motor_step(self.position, self.integral, self.set_point, s, data.ten_length[self.tendons],
                                            k, r.droop, r.kp, r.ki, r.max_speed, self.implicit_step, dt)
        self.position, self.integral, self.set_point = x_new, integral, s.copy()
        data.ctrl[self.actuators] = ctrl


def arm_motor_bank(model, actuators: Array, tendons: Array, options: ModelOptions) -> MotorBank:
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
    """The run's actuation with motors (``scenario.simulate.Simulation.actuate``).

    The controller's commands are the motors' set-points: each arm's cable lengths and
    the gripper cable go through their motor banks (elastic model: PI encoder loops with
    speed and force limits; lumped: straight to the actuators, as before), the spindle
    speed to its own speed loop unchanged.
    """

    def __init__(self, model, handles, geometry: ArmGeometry, options: ModelOptions, tools) -> None:
        for arm in handles.arms:
            if len(handles.cable_actuators[arm]) != 3 * geometry.n_sections:
                raise ValueError(f"{arm}: {len(handles.cable_actuators[arm])} cable actuators for {geometry.n_sections} sections")
        self.banks = {
            arm: arm_motor_bank(model, handles.cable_actuators[arm], handles.cable_tendons[arm], options)
            for arm in handles.arms
        }
        grip = int(handles.gripper_actuator)
        ratings = MotorRatings(tools.gripper_cable_speed, tools.gripper_max_force, options.motor_kp, options.motor_ki)
        self.gripper = MotorBank(
            model, [grip], [int(model.actuator_trnid[grip, 0])], ratings, ideal=options.cable_model == "lumped"  # type: ignore[arg-type]
        )
        self.spindle = int(handles.spindle_actuator)
        self._fused = self._fuse(model) if options.cable_model != "lumped" else None
        self._views: tuple | None = None  # the banks' state as views into the fused state
        self._state: tuple = ()  # the fused (3, n) state behind those views and the set-point scratch
        self._data = None  # the MjData whose arrays ``_arrays`` holds
        self._arrays: tuple = ()

    def _fuse(self, model) -> dict:
        """Per-element constants of every elastic cable motor and the gripper motor, in one vector.

        ``MotorBank.command`` per bank and this fused update (``_drive_motors``, compiled) do
        the same float operations per element in the same order (scalar ratings become
        per-element values), so the results are bit-identical; only the per-call overhead is shared.
        """
        banks = [*self.banks.values(), self.gripper]
        nc = sum(len(b.actuators) for b in self.banks.values())

        def per(f) -> Array:
            return np.concatenate([np.full(len(b.actuators), float(f(b))) for b in banks])

        bounds = np.cumsum([0] + [len(b.actuators) for b in banks])
        n = int(bounds[-1])
        const = np.zeros((_N_CONST, n))  # rows: _EA, _LEAD, _VG, _H, _DROOP, _KP, _KI, _VMAX (gripper: EA, LEAD, VG unused)
        const[_EA, :nc] = np.concatenate([b.ea for b in self.banks.values()])
        const[_LEAD, :nc] = np.concatenate([b.lead for b in self.banks.values()])
        const[_VG] = per(lambda b: b.velocity_gain)
        const[_H] = per(lambda b: b.implicit_step)
        const[_DROOP] = per(lambda b: b.ratings.droop)
        const[_KP] = per(lambda b: b.ratings.kp)
        const[_KI] = per(lambda b: b.ratings.ki)
        const[_VMAX] = per(lambda b: b.ratings.max_speed)
        return dict(
            banks=banks, nc=nc, slices=[slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)],
            index=np.stack([np.concatenate([b.actuators for b in banks]),
                            np.concatenate([b.tendons for b in banks])]).astype(np.int64),
            const=const, model=model, kernel=_drive_kernel(),
        )

    def __call__(self, sim, commands) -> None:
        dt = 0.0 if sim.tick < 0 else sim.control_period
        data = sim.data
        f = self._fused
        if f is not None and dt > 0.0 and all(b._started for b in f["banks"]):
            self._fused_command(data, commands, dt)
        else:
            self._views = None
            for arm, bank in self.banks.items():
                bank.command(data, commands.cable_lengths[arm], dt)
            self.gripper.command(data, np.array([commands.gripper_cable], dtype=float), dt)
        data.ctrl[self.spindle] = commands.spindle_speed

    def _fused_command(self, data, commands, dt: float) -> None:
        """``MotorBank.command`` of every bank at once (elastic model, dt > 0, banks started).

        The motors' state lives in one (3, n) array (position, integral, set-point) updated in
        place; each bank's ``position``/``integral``/``set_point`` are views of its columns.
        A bank whose attributes were replaced since (its own ``command``/``reset``) is gathered anew.
        """
        f = self._fused
        assert f is not None
        banks = f["banks"]
        views = self._views
        if views is None or any(b.position is not v[0] or b.integral is not v[1] or b.set_point is not v[2]
                                for b, v in zip(banks, views, strict=True)):
            state = np.stack([np.concatenate([b.position for b in banks]), np.concatenate([b.integral for b in banks]),
                              np.concatenate([b.set_point for b in banks])])
            out = []
            for b, sl in zip(banks, f["slices"], strict=True):
                b.position, b.integral, b.set_point = state[0, sl], state[1, sl], state[2, sl]
                out.append((b.position, b.integral, b.set_point))
            self._views = tuple(out)
            self._state = (state, np.empty(state.shape[1]))
        state, s = self._state
        for arm, sl in zip(self.banks, f["slices"], strict=False):
            s[sl] = commands.cable_lengths[arm]
        s[f["nc"]] = commands.gripper_cable
        if data is not self._data:
            model = f["model"]
            self._data = data
            self._arrays = (data.ten_length, data.ctrl, model.actuator_gainprm, model.actuator_biasprm)
        ten_length, ctrl, gainprm, biasprm = self._arrays
        f["kernel"](state, s, ten_length, ctrl, gainprm, biasprm, f["index"], f["const"], f["nc"], dt)


# Rows of MotorDrive's per-motor constants (``_drive_motors``'s ``const``).
_EA, _LEAD, _VG, _H, _DROOP, _KP, _KI, _VMAX = range(8)
_N_CONST = 8


def _drive_motors(state, s, ten_length, ctrl, gainprm, biasprm, index, const, nc, dt) -> None:  # pragma: no cover - numba
    """One tick of every motor of ``MotorDrive``, element by element: the cables' stiffness
    write (``_write_cable_stiffness``, the first ``nc`` motors) and the PI loop (``_motor_step``).

    The same float operations in the same order as those two numpy functions (their array
    expressions evaluated per element), so the results are bit-identical to them. ``state``
    rows: position, integral, set-point (updated in place); ``index`` rows: actuator, tendon.
    """
    for i in range(s.shape[0]):
        act = index[0, i]
        x = state[0, i]
        integral = state[1, i]
        s_i = s[i]
        length = ten_length[index[1, i]]
        h = const[_H, i]
        if i < nc:
            k = const[_EA, i] / (const[_LEAD, i] + length)
        else:
            k = gainprm[act, 0]
        taut = length > x
        if i < nc:
            gainprm[act, 0] = k
            biasprm[act, 1] = -k
            biasprm[act, 2] = -(const[_VG, i] + (k * h if taut else 0.0))
        droop, kp, ki, vmax = const[_DROOP, i], const[_KP, i], const[_KI, i], const[_VMAX, i]
        v_ff = (s_i - state[2, i]) / dt
        dk = droop * k if taut else 0.0
        a = kp + ki * dt
        x_new = (x + dt * (v_ff + a * s_i + ki * integral + dk * length)) / (1.0 + dt * (a + dk))
        v_cmd = v_ff + a * (s_i - x_new) + ki * integral
        if abs(v_cmd) > vmax:
            v_sat = min(max(v_cmd, -vmax), vmax)
            x_new = (x + dt * (v_sat + dk * length)) / (1.0 + dt * dk)
        else:
            integral = integral + dt * (s_i - x_new)
        ctrl[act] = 0.5 * (x + x_new) + h * (x_new - x) / dt
        state[0, i] = x_new
        state[1, i] = integral
        state[2, i] = s_i


_KERNEL: list = []


def _drive_kernel():
    """``_drive_motors`` compiled by numba (or loaded from its cache) on first use, outside any tick."""
    if not _KERNEL:
        from ..plant.jit import jit, sigint_deferred

        with sigint_deferred():
            kernel = jit(_drive_motors)
            one = np.zeros(1)
            kernel(np.zeros((3, 1)), one, one, np.zeros(1), np.zeros((1, 10)), np.zeros((1, 10)),
                   np.zeros((2, 1), dtype=np.int64), np.ones((_N_CONST, 1)), 1, 1.0)
        _KERNEL.append(kernel)
    return _KERNEL[0]
