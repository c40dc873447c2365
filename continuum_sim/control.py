"""Per-arm controller (SPEC §7): planned shape → cable lengths → motor position loops.

The motor loops themselves are the model's tendon position actuators (one per cable,
tension-only). This module chooses their set-points:

* ``open`` (the paper's method): cable lengths of the planned PCC shape, shortened by a
  pre-tension offset ``pretension / k`` (each cable's own stiffness) so no cable goes slack;
* ``closed`` (ours): the same, but the commanded shape is the planned one plus a
  correction that integrates the measured tool-pose error through the PCC Jacobian
  (damped least squares in bending coordinates), the improvement the paper suggests.

It holds only the controller's own state (the integrated correction); the simulation
state is read from ``MjData`` each control tick.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from . import kinematics as kin
from .configio import ConfigError, require_positive, require_range
from .geometry import ArmGeometry

Array = NDArray[np.float64]

_CONTROLLER_SPEC = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_]\w*")


@dataclass(frozen=True)
class ControlConfig:
    """Controller settings; ``mode`` switches between the paper's open loop and ours."""

    mode: Literal["open", "closed"] = "closed"
    # "" = the built-in controller named by ``mode``; "package.module:ClassName" = your own class
    # (``continuum_sim.controllers.Controller`` protocol; checked when the run starts).
    controller: str = ""
    rate_hz: float = 125.0  # control (set-point) update rate (rounded to whole steps); the motor loops run every step
    # N, tension every cable keeps at the planned shape. 30 N (15 % of the 200 N motor rating):
    # with the strain-limited leaves a bend needs ~100 N on its inner cables, whose stretch
    # unloads the outer ones; at 10 N a quarter of the task's records had a slack cable.
    pretension: float = 30.0
    outer_gain: float = 8.0  # 1/s, integral gain of the task-space correction (gain_mode "plant": the loop's crossover ω_c)
    # "fixed": the correction integrates outer_gain × the bending-coordinate error; "plant":
    # the gain is derived per arm from the plant (continuum_sim.gains, docs/plant.md "Outer-loop
    # gains from the plant"): G = ω_c·R⁻¹ with R the static transmission (cable stretch against
    # the hinge stiffness), ω_c = min(outer_gain, mode_fraction × the arm's first bending mode ω₁).
    gain_mode: Literal["fixed", "plant"] = "fixed"
    mode_fraction: float = 0.5  # gain_mode "plant": cap of the crossover as a fraction of the arm's first mode ω₁
    # Proportional share of the pose error added to the command. It feeds the pose measured
    # every tick straight back: at 2 it rang the ~20-25 Hz cable-arm mode (docs/plant.md).
    outer_proportional: float = 0.5
    orientation_weight: float = 0.1  # m/rad: how much 1 rad of tool tilt counts against 1 m
    damping: float = 1e-4  # damped-least-squares regulariser (m²)
    max_correction_deg: float = 15.0  # bound on the correction per section (bending angle)
    # Tension keeping (closed mode): each section's three cables are shortened together
    # (a common mode that does not bend the section) until its slackest cable pulls at
    # least min_tension, as measured by the motors; 0 switches it off.
    min_tension: float = 3.0  # N
    tension_gain: float = 5.0  # 1/s
    max_extra_tension: float = 30.0  # N, bound on the added common-mode pull per section

    def __post_init__(self) -> None:
        if self.mode not in ("open", "closed"):
            raise ConfigError("mode", f"must be 'open' or 'closed' (got {self.mode!r})")
        if self.controller and not _CONTROLLER_SPEC.fullmatch(self.controller):
            raise ConfigError(
                "controller", f"must be empty or 'package.module:ClassName' (got {self.controller[:80]!r})"
            )
        require_range("rate_hz", self.rate_hz, 1.0, 10000.0, low_inclusive=True)
        require_range("pretension", self.pretension, 0.0, 1000.0, low_inclusive=True)
        require_range("outer_gain", self.outer_gain, 0.0, 1000.0, low_inclusive=True)
        if self.gain_mode not in ("fixed", "plant"):
            raise ConfigError("gain_mode", f"must be 'fixed' or 'plant' (got {self.gain_mode!r})")
        require_range("mode_fraction", self.mode_fraction, 0.0, 1.0)
        require_range("outer_proportional", self.outer_proportional, 0.0, 10.0, low_inclusive=True)
        require_positive("orientation_weight", self.orientation_weight)
        require_range("damping", self.damping, 0.0, 1.0, low_inclusive=True)
        require_range("max_correction_deg", self.max_correction_deg, 0.0, 90.0, low_inclusive=True)
        require_range("min_tension", self.min_tension, 0.0, 1000.0, low_inclusive=True)
        require_range("tension_gain", self.tension_gain, 0.0, 1000.0, low_inclusive=True)
        require_range("max_extra_tension", self.max_extra_tension, 0.0, 1000.0, low_inclusive=True)


def _rotation_error(R_target: Array, R_actual: Array) -> Array:
    """log(R_target R_actualᵀ)^∨: the rotation that carries the actual frame onto the target."""
    return np.array(_rotation_error_scalar(np.asarray(R_target).ravel().tolist(), np.asarray(R_actual).ravel().tolist()))


def _rotation_error_scalar(t: list[float], a: list[float]) -> list[float]:
    """``_rotation_error`` on row-major 3×3 lists: the control tick's version, no numpy calls.

    Only the skew part and the trace of E = R_t R_aᵀ are needed: E_ij = Σ_k t_ik a_jk.
    """
    e00 = t[0] * a[0] + t[1] * a[1] + t[2] * a[2]
    e11 = t[3] * a[3] + t[4] * a[4] + t[5] * a[5]
    e22 = t[6] * a[6] + t[7] * a[7] + t[8] * a[8]
    e01 = t[0] * a[3] + t[1] * a[4] + t[2] * a[5]
    e10 = t[3] * a[0] + t[4] * a[1] + t[5] * a[2]
    e02 = t[0] * a[6] + t[1] * a[7] + t[2] * a[8]
    e20 = t[6] * a[0] + t[7] * a[1] + t[8] * a[2]
    e12 = t[3] * a[6] + t[4] * a[7] + t[5] * a[8]
    e21 = t[6] * a[3] + t[7] * a[4] + t[8] * a[5]
    vx, vy, vz = 0.5 * (e21 - e12), 0.5 * (e02 - e20), 0.5 * (e10 - e01)
    sin = math.sqrt(vx * vx + vy * vy + vz * vz)
    cos = 0.5 * (e00 + e11 + e22 - 1.0)
    angle = math.atan2(sin, cos)
    if angle > 3.0:  # far from any useful correction; fall back to the robust log
        E = np.array([[e00, e01, e02], [e10, e11, e12], [e20, e21, e22]])
        return kin.log_so3(E).tolist()
    scale = angle / sin if sin > 1e-12 else 1.0
    return [vx * scale, vy * scale, vz * scale]


class ArmController:
    """Set-points for one arm's cable actuators, open or closed loop.

    ``roll_free``: the tool is symmetric about its axis (the grinder's cutter), so the loop
    corrects the tool point and the axis direction only (5 task coordinates). Asking the
    6-coordinate PCC arm for a roll about its own tool axis as well is the worst-conditioned
    request it can get: the correction grew to the 15° bound per section and left a
    0.4 mm position error standing at the cut start.
    """

    def __init__(
        self,
        geometry: ArmGeometry,
        config: ControlConfig,
        base: Array,
        tool_length: float,
        cable_kp: float | Array,
        roll_free: bool = False,
        gain: Array | None = None,
        compiled: bool = True,
    ) -> None:
        """``gain``: the outer loop's (2n × 2n) integral gain matrix (1/s, ``gains.plant_gain``);
        None integrates with the scalar ``config.outer_gain``. ``compiled`` False: the Python
        tick (same numbers), for a controller used once (loading the kernels costs more)."""
        self.geometry = geometry
        self.roll_free = bool(roll_free)
        self.config = config
        self.gain = None if gain is None else np.asarray(gain, dtype=float)
        self.base = np.asarray(base, dtype=float)
        self._base_rot_rows = self.base[:3, :3].T.tolist()  # rows of Rᵀ: world -> arm base frame
        self.tool_length = float(tool_length)
        # Per-cable stiffness (N/m): the elastic cables' EA/L (motors.cable_stiffness), or the
        # lumped servo's gain; the pre-tension offset of each cable is its own T/k.
        stiffness = np.broadcast_to(np.asarray(cable_kp, dtype=float), (3 * geometry.n_sections,)).copy()
        self.offset = config.pretension / stiffness
        self.correction = np.zeros(2 * geometry.n_sections)
        self.proportional = np.zeros(2 * geometry.n_sections)
        self._max_bend = np.broadcast_to(geometry.max_bend, (geometry.n_sections,)).astype(float).tolist()
        self.max_correction = np.radians(config.max_correction_deg)
        self._pose = kin.ArmKernel(geometry, self.tool_length)
        self._cables = kin.CableKernel(geometry)
        self._cable_section = kin.cable_sections(geometry)
        # A section's common mode moves its three cables together: tension per metre of it.
        self.cable_kp = stiffness.reshape(geometry.n_sections, 3).mean(axis=1)
        self.extra = np.zeros(geometry.n_sections)  # common-mode shortening per section (m), tension keeping
        self._regulariser = config.damping * np.eye(5 if roll_free else 6)
        self._holding = False
        self._set_points: tuple[object, bytes, Array] | None = None  # (w, extra, lengths) of the last tick
        self.last_command: list[float] = []  # bending coordinates of the last set-points (for recording)
        # The tick runs through the numba kernels (``control_kernels``, bit-identical to the
        # Python methods below, which stay as the reference and the fallback); False: Python.
        self.compiled = bool(compiled)
        if not self.compiled:
            return
        from .control_kernels import dposv_address, kernels  # numba: imported when a controller is built, not with the config

        self._kernels = kernels()
        self._dposv = dposv_address()
        self._uplo, self._lapack_ints = np.array([ord("U")], dtype=np.uint8), np.zeros(5, dtype=np.int32)
        S, m = geometry.n_sections, 5 if roll_free else 6
        self._section_length = np.array([L for L, _ in self._pose._sections])
        self._section_segments = np.array([n for _, n in self._pose._sections])
        self._cable_segments = np.array([n for n, _ in self._cables._sections])
        self._cable_halves = np.array([h for _, h in self._cables._sections])
        self._base_rot = np.ascontiguousarray(self.base[:3, :3].T)
        self._max_bend_array = np.array(self._max_bend)
        self._gain_matrix = np.zeros((0, 0)) if self.gain is None else np.ascontiguousarray(self.gain)
        self._w = np.zeros(2 * S)
        self._r = np.zeros(3)
        self._R, self._p, self._J_flat = np.zeros(9), np.zeros(3), np.zeros(6 * 2 * S)
        self._J, self._error, self._A = np.zeros((m, 2 * S)), np.zeros(m), np.zeros((m, m))
        self._x, self._a_work, self._no_tensions = np.zeros(m), np.zeros((m, m)), np.zeros(3 * S)

    def _commanded(self, q_plan) -> list[float]:
        # Scalar per section: this runs twice per arm per control tick.
        w = []
        c, p = self.correction, self.proportional
        for k in range(len(self.correction) // 2):
            theta, phi = float(q_plan[2 * k]), float(q_plan[2 * k + 1])
            u = theta * math.cos(phi) + c[2 * k] + p[2 * k]
            v = theta * math.sin(phi) + c[2 * k + 1] + p[2 * k + 1]
            bend, max_bend = math.hypot(u, v), self._max_bend[k]
            if bend > max_bend:
                u, v = u * max_bend / bend, v * max_bend / bend
            w.append(u)
            w.append(v)
        return w

    def update(
        self,
        q_plan: Array,
        tcp_plan: Array,
        tcp_pos: Array,
        tcp_mat: Array,
        dt: float,
        holding: bool = False,
        tensions: Array | None = None,
    ) -> Array:
        """One control tick: returns the cable-length set-points (actuator controls).

        ``tensions``: the cables' measured tensions (N, ≥ 0), for tension keeping in
        closed mode; None leaves the common-mode shortening as it is.

        ``holding``: the tool grips something fixed (the gripper on the still-welded
        sample). The command is then held where it was when the grasp closed (proportional
        share folded into the correction, no integration): the object, not the arm, sets the
        tool pose, and an integrator fighting it winds up a correction that either drags
        the grasp along the object or flings the object when it comes free.
        """
        if holding:
            if not self._holding:
                self.correction += self.proportional
                self.proportional = np.zeros_like(self.proportional)
            dt = 0.0
        self._holding = holding
        if self.compiled:
            return self._update_compiled(q_plan, tcp_plan, tcp_pos, tcp_mat, dt, tensions)
        w = self._commanded(q_plan)
        if self.config.mode == "closed" and dt > 0.0:
            self._integrate(w, tcp_plan, tcp_pos, tcp_mat, dt)
            w = self._commanded(q_plan)
        self.last_command = w
        if self.config.mode == "closed" and tensions is not None and dt > 0.0 and self.config.min_tension > 0.0:
            self._keep_tension(np.asarray(tensions, dtype=float), dt)
        return self._cable_set_points(w)

    def _update_compiled(
        self, q_plan: Array, tcp_plan: Array, tcp_pos: Array, tcp_mat: Array, dt: float, tensions: Array | None
    ) -> Array:
        """``update`` after the holding logic in one numba call (same numbers as the Python methods).

        The set-points are computed every tick: the Python path's reuse while (w, extra) stand
        still only saved the cable kernel, and returns the same numbers.
        """
        k, cfg, w = self._kernels, self.config, self._w
        q = np.asarray(q_plan, dtype=float)
        integrate = cfg.mode == "closed" and dt > 0.0
        keep = cfg.mode == "closed" and tensions is not None and dt > 0.0 and cfg.min_tension > 0.0
        measured = self._no_tensions if tensions is None else np.asarray(tensions, dtype=float)
        lengths = np.empty(len(self.offset))
        c = self._cables
        cables = (
            self._cable_segments, self._cable_halves, c._pair_section, c._pair_holes, c._gather,
            self.offset, self._cable_section, lengths,
        )
        step = (
            self._gain_matrix, self.gain is not None, cfg.outer_gain, dt, cfg.outer_proportional, float(self.max_correction)
        )
        tension = (keep, measured, self.extra, self.cable_kp, cfg.min_tension, cfg.tension_gain, cfg.max_extra_tension)
        if not integrate:
            k["commanded"](q, self.correction, self.proportional, self._max_bend_array, w)
            k["tick_end"](False, self._J, self._x, self.correction, self.proportional, *step, q, self._max_bend_array, w,
                          *tension, *cables)
            self.last_command = w.tolist()
            return lengths
        plan = np.asarray(tcp_plan, dtype=float)
        pos = np.asarray(tcp_pos, dtype=float)
        mat = np.asarray(tcp_mat, dtype=float).reshape(3, 3)
        system = (
            self._section_length, self._section_segments, self.tool_length, cfg.orientation_weight, self.roll_free,
            self._regulariser, self._r,
        )
        outputs = (self._R, self._p, self._J_flat, self._J, self._error, self._A)
        status = k["tick"](
            q, self.correction, self.proportional, self._max_bend_array, w, plan, pos, mat, self._base_rot,
            *system, *outputs, self._dposv, self._uplo, self._lapack_ints, self._a_work, self._x, *step, *tension, *cables,
        )
        if status:  # the rare cases, as the Python path takes them; w holds the commanded shape
            if status == 1:  # beyond 3 rad: the rotation error from the robust log, then the same system
                self._r[:] = _rotation_error_scalar(plan[:3, :3].ravel().tolist(), mat.ravel().tolist())
                k["tick_system"](plan, pos, mat, self._base_rot, w, *system, True, *outputs)
            x = _solve_spd(self._A, self._error)  # LAPACK, or numpy's solve where A is not positive definite
            k["tick_end"](True, self._J, x, self.correction, self.proportional, *step, q, self._max_bend_array, w,
                          *tension, *cables)
        self.last_command = w.tolist()
        return lengths

    def _cable_set_points(self, w: list[float]) -> Array:
        """Cable lengths of shape ``w`` less the pre-tension offset and the common mode.

        Reused while neither changes (the gripper arm holding the welded sample through the
        whole cut): the same numbers without the cable kernel.
        """
        key, extra = tuple(w), self.extra.tobytes()
        if self._set_points is not None and self._set_points[0] == key and self._set_points[1] == extra:
            return self._set_points[2].copy()
        lengths = self._cables.lengths(w) - self.offset - self.extra[self._cable_section]
        self._set_points = (key, extra, lengths)
        return lengths.copy()

    def _keep_tension(self, tensions: Array, dt: float) -> None:
        """Integrate each section's common-mode shortening toward min_tension on its slackest cable.

        The three cables of a section span its two bending coordinates plus one common
        mode; shortening all three by the same length raises their tensions together
        (by kp per metre) and leaves the bend alone, so the pose loop is not disturbed.
        """
        cfg = self.config
        slackest = tensions.reshape(len(self.extra), 3).min(axis=1)  # cables come three per section, base to tip
        self.extra += cfg.tension_gain * (cfg.min_tension - slackest) / self.cable_kp * dt
        np.clip(self.extra, 0.0, cfg.max_extra_tension / self.cable_kp, out=self.extra)

    def _integrate(self, w, tcp_plan: Array, tcp_pos: Array, tcp_mat: Array, dt: float) -> None:
        """Integrate the weighted tool-pose error through the PCC Jacobian (damped least squares).

        Written for the control tick (250 calls per simulated second): the 3-vectors in
        plain floats, numpy only for the 6×6 algebra.
        """
        plan = np.asarray(tcp_plan).tolist()
        mat = np.asarray(tcp_mat).ravel().tolist()
        b = self._base_rot_rows  # rows of Rᵀ (base frame ← world)
        dx, dy, dz = plan[0][3] - float(tcp_pos[0]), plan[1][3] - float(tcp_pos[1]), plan[2][3] - float(tcp_pos[2])
        rx, ry, rz = _rotation_error_scalar(plan[0][:3] + plan[1][:3] + plan[2][:3], mat)
        ow = self.config.orientation_weight
        rows = [
            b[0][0] * dx + b[0][1] * dy + b[0][2] * dz,
            b[1][0] * dx + b[1][1] * dy + b[1][2] * dz,
            b[2][0] * dx + b[2][1] * dy + b[2][2] * dz,
            ow * (b[0][0] * rx + b[0][1] * ry + b[0][2] * rz),
            ow * (b[1][0] * rx + b[1][1] * ry + b[1][2] * rz),
            ow * (b[2][0] * rx + b[2][1] * ry + b[2][2] * rz),
        ]
        _, _, J_flat = self._pose.pose_jacobian(w)
        J = np.array(J_flat).reshape(6, -1)
        J[3:] *= ow
        if self.roll_free:  # keep the angular rows about the tool's own x and y axes only
            # Tool x and y axes (columns 0, 1 of the world tool frame) in the base frame.
            axes = [
                [b[i][0] * mat[0 + j] + b[i][1] * mat[3 + j] + b[i][2] * mat[6 + j] for i in range(3)] for j in (0, 1)
            ]
            e = rows[3:]
            rows = rows[:3] + [sum(a * v for a, v in zip(axis, e)) for axis in axes]
            J = np.vstack((J[:3], np.array(axes) @ J[3:]))
        error = np.array(rows)
        step = J.T @ _solve_spd(J @ J.T + self._regulariser, error)
        if self.gain is None:
            self.correction += self.config.outer_gain * dt * step
        else:
            self.correction += dt * (self.gain @ step)
        self.proportional = self.config.outer_proportional * step
        # Bound the correction per section so a transient cannot wind it up.
        c = self.correction
        for k in range(len(c) // 2):
            norm = math.hypot(c[2 * k], c[2 * k + 1])
            if norm > self.max_correction:
                c[2 * k : 2 * k + 2] *= self.max_correction / norm


@functools.cache
def _dposv():  # noqa: ANN202 - returns the LAPACK routine
    """LAPACK's dposv, imported on first use: loading a configuration should not import scipy."""
    from scipy.linalg.lapack import dposv

    return dposv


def _solve_spd(A: Array, b: Array) -> Array:
    """A⁻¹ b for a symmetric positive definite A: LAPACK's posv, a third of np.linalg.solve's overhead."""
    _, x, info = _dposv()(A, b)
    if info != 0:
        return np.linalg.solve(A, b)  # type: ignore[return-value]
    return x

