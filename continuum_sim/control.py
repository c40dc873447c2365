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
    rate_hz: float = 250.0  # control (set-point) update rate
    pretension: float = 10.0  # N, tension every cable keeps at the planned shape
    outer_gain: float = 4.0  # 1/s, integral gain of the task-space correction
    orientation_weight: float = 0.1  # m/rad: how much 1 rad of tool tilt counts against 1 m
    damping: float = 1e-4  # damped-least-squares regulariser (m²)
    max_correction_deg: float = 15.0  # bound on the correction per section (bending angle)

    def __post_init__(self) -> None:
        if self.mode not in ("open", "closed"):
            raise ConfigError("mode", f"must be 'open' or 'closed' (got {self.mode!r})")
        require_range("rate_hz", self.rate_hz, 1.0, 10000.0, low_inclusive=True)
        require_range("pretension", self.pretension, 0.0, 1000.0, low_inclusive=True)
        require_range("outer_gain", self.outer_gain, 0.0, 1000.0, low_inclusive=True)
        require_positive("orientation_weight", self.orientation_weight)
        require_range("damping", self.damping, 0.0, 1.0, low_inclusive=True)
        require_range("max_correction_deg", self.max_correction_deg, 0.0, 90.0, low_inclusive=True)


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
        self.base_rot_t = self.base[:3, :3].T
        self.tool_length = float(tool_length)
        self.offset = config.pretension / cable_kp
        self.correction = np.zeros(2 * geometry.n_sections)
        self.weights = np.array([1.0, 1.0, 1.0] + [config.orientation_weight] * 3)
        self.max_bend = geometry.max_bend

    def reset(self) -> None:
        self.correction[:] = 0.0

    def commanded_bending(self, q_plan: Array) -> Array:
        """Planned shape plus the closed-loop correction, kept inside the bending limits."""
        w = kin.to_bending(q_plan) + self.correction
        theta = np.hypot(w[0::2], w[1::2])
        scale = np.minimum(1.0, self.max_bend / np.maximum(theta, 1e-15))
        w[0::2] *= scale
        w[1::2] *= scale
        return w

    def update(self, q_plan: Array, tcp_plan: Array, tcp_pos: Array, tcp_mat: Array, dt: float) -> Array:
        """One control tick: returns the cable-length set-points (actuator controls)."""
        if self.config.mode == "closed":
            self._integrate(q_plan, tcp_plan, tcp_pos, tcp_mat, dt)
        w = self.commanded_bending(q_plan)
        return kin.cable_lengths_bending(self.geometry, w) - self.offset

    def _integrate(self, q_plan: Array, tcp_plan: Array, tcp_pos: Array, tcp_mat: Array, dt: float) -> None:
        rot_t = self.base_rot_t
        e_pos = rot_t @ (tcp_plan[:3, 3] - tcp_pos)
        e_rot = rot_t @ kin.log_so3(tcp_plan[:3, :3] @ np.asarray(tcp_mat).reshape(3, 3).T)
        error = np.concatenate([e_pos, e_rot]) * self.weights
        w = self.commanded_bending(q_plan)
        _, J = kin.jacobian_bending(self.geometry, w, tool_length=self.tool_length)
        J = J * self.weights[:, None]
        step = J.T @ np.linalg.solve(J @ J.T + self.config.damping * np.eye(6), error)
        self.correction += self.config.outer_gain * dt * step
        # Bound the correction per section so a transient cannot wind it up.
        limit = np.radians(self.config.max_correction_deg)
        for k in range(self.geometry.n_sections):
            norm = np.hypot(*self.correction[2 * k : 2 * k + 2])
            if norm > limit:
                self.correction[2 * k : 2 * k + 2] *= limit / norm
