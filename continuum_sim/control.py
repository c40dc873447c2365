"""Per-arm controller (SPEC §7): planned shape → cable lengths → motor position loops.

The motor loops themselves are the model's tendon position actuators (one per cable,
tension-only). This module chooses their set-points:

* ``open`` (the paper's method): cable lengths of the planned PCC shape, shortened by a
  pre-tension offset ``pretension / kp`` so no cable goes slack;
* ``closed`` (ours): the same, but the commanded shape is the planned one plus a
  correction that integrates the measured tool-pose error through the PCC Jacobian
  (damped least squares in bending coordinates), the improvement the paper suggests.

It holds only the controller's own state (the integrated correction); the simulation
state is read from ``MjData`` each control tick.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from . import kinematics as kin
from .configio import ConfigError, require_positive, require_range
from .geometry import ArmGeometry

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ControlConfig:
    """Controller settings; ``mode`` switches between the paper's open loop and ours."""

    mode: Literal["open", "closed"] = "closed"
    rate_hz: float = 100.0  # control (set-point) update rate; the motor loops run every step
    pretension: float = 10.0  # N, tension every cable keeps at the planned shape
    outer_gain: float = 4.0  # 1/s, integral gain of the task-space correction
    outer_proportional: float = 2.0  # proportional share of the pose error added to the command
    orientation_weight: float = 0.1  # m/rad: how much 1 rad of tool tilt counts against 1 m
    damping: float = 1e-4  # damped-least-squares regulariser (m²)
    max_correction_deg: float = 15.0  # bound on the correction per section (bending angle)

    def __post_init__(self) -> None:
        if self.mode not in ("open", "closed"):
            raise ConfigError("mode", f"must be 'open' or 'closed' (got {self.mode!r})")
        require_range("rate_hz", self.rate_hz, 1.0, 10000.0, low_inclusive=True)
        require_range("pretension", self.pretension, 0.0, 1000.0, low_inclusive=True)
        require_range("outer_gain", self.outer_gain, 0.0, 1000.0, low_inclusive=True)
        require_range("outer_proportional", self.outer_proportional, 0.0, 10.0, low_inclusive=True)
        require_positive("orientation_weight", self.orientation_weight)
        require_range("damping", self.damping, 0.0, 1.0, low_inclusive=True)
        require_range("max_correction_deg", self.max_correction_deg, 0.0, 90.0, low_inclusive=True)


def _rotation_error(R_target: Array, R_actual: Array) -> Array:
    """log(R_target R_actualᵀ)^∨: the rotation that carries the actual frame onto the target."""
    E = R_target @ R_actual.T
    vee = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    sin = float(np.linalg.norm(vee))
    cos = 0.5 * (float(np.trace(E)) - 1.0)
    angle = float(np.arctan2(sin, cos))
    if angle > 3.0:  # far from any useful correction; fall back to the robust log
        return kin.log_so3(E)
    return vee * (angle / sin if sin > 1e-12 else 1.0)


class ArmController:
    """Set-points for one arm's cable actuators, open or closed loop."""

    def __init__(
        self,
        geometry: ArmGeometry,
        config: ControlConfig,
        base: Array,
        tool_length: float,
        cable_kp: float,
    ) -> None:
        self.geometry = geometry
        self.config = config
        self.base = np.asarray(base, dtype=float)
        self.base_rot_t = self.base[:3, :3].T.copy()
        self.tool_length = float(tool_length)
        self.offset = config.pretension / cable_kp
        self.correction = np.zeros(2 * geometry.n_sections)
        self.proportional = np.zeros(2 * geometry.n_sections)
        self.weights = np.array([1.0, 1.0, 1.0] + [config.orientation_weight] * 3)
        self.max_bend = geometry.max_bend
        self.max_correction = np.radians(config.max_correction_deg)
        self._pose = kin.ArmKernel(geometry, self.tool_length)
        self._cables = kin.CableKernel(geometry)
        self._regulariser = config.damping * np.eye(6)

    def reset(self) -> None:
        self.correction[:] = 0.0
        self.proportional[:] = 0.0

    def commanded_bending(self, q_plan: Array) -> Array:
        """Planned shape plus the closed-loop correction, kept inside the bending limits."""
        w = kin.to_bending(q_plan) + self.correction + self.proportional
        theta = np.hypot(w[0::2], w[1::2])
        scale = np.minimum(1.0, self.max_bend / np.maximum(theta, 1e-15))
        w[0::2] *= scale
        w[1::2] *= scale
        return w

    def update(
        self, q_plan: Array, tcp_plan: Array, tcp_pos: Array, tcp_mat: Array, dt: float, holding: bool = False
    ) -> Array:
        """One control tick: returns the cable-length set-points (actuator controls).

        ``holding``: the tool grips something fixed. The proportional share is then off: a
        stiff grasp contact in the loop makes it chatter; the integral share stays.
        """
        w = self.commanded_bending(q_plan)
        if self.config.mode == "closed" and dt > 0.0:
            self._integrate(w, tcp_plan, np.asarray(tcp_pos), np.asarray(tcp_mat).reshape(3, 3), dt, holding)
            w = self.commanded_bending(q_plan)
        return self._cables.lengths(w) - self.offset

    def _integrate(self, w: Array, tcp_plan: Array, tcp_pos: Array, tcp_mat: Array, dt: float, holding: bool) -> None:
        rot_t = self.base_rot_t
        error = np.empty(6)
        error[:3] = rot_t @ (tcp_plan[:3, 3] - tcp_pos)
        error[3:] = rot_t @ _rotation_error(tcp_plan[:3, :3], tcp_mat)
        error *= self.weights
        _, _, J_flat = self._pose.pose_jacobian(w)
        J = np.asarray(J_flat).reshape(6, -1) * self.weights[:, None]
        step = J.T @ np.linalg.solve(J @ J.T + self._regulariser, error)
        self.correction += self.config.outer_gain * dt * step
        self.proportional = (0.0 if holding else self.config.outer_proportional) * step
        # Bound the correction per section so a transient cannot wind it up.
        c = self.correction.reshape(-1, 2)
        norms = np.hypot(c[:, 0], c[:, 1])
        too_big = norms > self.max_correction
        if np.any(too_big):
            c[too_big] *= (self.max_correction / norms[too_big])[:, None]
