"""One arm's controller (SPEC §7): planned shape → cable lengths → motor position loops.

The motor loops themselves are the model's tendon position actuators (one per cable,
tension-only). This module chooses their set-points:

* ``open`` (the paper's method): cable lengths of the planned PCC shape, shortened by a
  pre-tension offset ``pretension / k`` (each cable's own stiffness) so no cable goes slack;
* ``closed`` (ours): the same, but the commanded shape is the planned one plus a
  correction that integrates the measured tool-pose error through the PCC Jacobian
  (damped least squares in bending coordinates), the improvement the paper suggests.

It holds only the controller's own state (the integrated correction); the simulation
state is read from ``MjData`` each control tick. The tick itself is compiled
(``control.kernels.tick``); this class sets it up and handles the holding logic.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .. import kinematics as kin
from ..geometry import ArmGeometry
from ..kinematics_kernels import cable_model, pose_model
from .config import ControlConfig
from .kernels import ROTATION_BEYOND_3_RAD, law_dtype, state_dtype, tick

Array = NDArray[np.float64]


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
    ) -> None:
        """``cable_kp``: per-cable stiffness (N/m), the elastic cables' EA/L
        (``motors.cable_stiffness``) or the lumped servo's gain; each cable's pre-tension
        offset is its own T/k. ``gain``: the outer loop's (2n × 2n) integral gain matrix
        (1/s, ``gains.plant_gain``); None integrates with the scalar ``config.outer_gain``."""
        S = geometry.n_sections
        self.geometry = geometry
        self.roll_free = bool(roll_free)
        self.config = config
        self.gain = None if gain is None else np.asarray(gain, dtype=float)
        self.base = np.asarray(base, dtype=float)
        self.tool_length = float(tool_length)
        stiffness = np.broadcast_to(np.asarray(cable_kp, dtype=float), (3 * S,)).copy()
        self.offset = config.pretension / stiffness
        self.max_correction = float(np.radians(config.max_correction_deg))
        # A section's common mode moves its three cables together: tension per metre of it.
        self.cable_kp = stiffness.reshape(S, 3).mean(axis=1)
        cables = cable_model(geometry)
        self.law = np.zeros(1, dtype=law_dtype(S, cables["pair_section"].shape[1]))
        law = self.law[0]
        law["pose"], law["cables"] = pose_model(geometry, self.tool_length)[0], cables[0]
        law["base_rot"] = self.base[:3, :3].T
        law["max_bend"] = np.broadcast_to(np.asarray(geometry.max_bend, dtype=float), (S,))
        law["offset"], law["cable_section"], law["cable_kp"] = self.offset, kin.cable_sections(geometry), self.cable_kp
        law["use_gain"] = self.gain is not None
        if self.gain is not None:
            law["gain"] = self.gain
        for name in ("outer_gain", "outer_proportional", "orientation_weight", "damping", "min_tension", "tension_gain",
                     "max_extra_tension"):
            law[name] = float(getattr(config, name))
        law["max_correction"], law["roll_free"] = self.max_correction, self.roll_free
        self.state = np.zeros(1, dtype=state_dtype(S))
        self._holding = False
        self._r = np.zeros(3)
        self._no_tensions = np.zeros(3 * S)
        self.last_command: list[float] = []  # bending coordinates of the last set-points (for recording)

    @property
    def correction(self) -> Array:
        """(2S,) rad, the integrated bending-coordinate correction."""
        return self.state["correction"][0]

    @property
    def proportional(self) -> Array:
        """(2S,) rad, the proportional share of the last step."""
        return self.state["proportional"][0]

    @property
    def extra(self) -> Array:
        """(S,) m, the common-mode shortening per section (tension keeping)."""
        return self.state["extra"][0]

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
        cfg = self.config
        if holding:
            if not self._holding:
                self.correction[:] += self.proportional
                self.proportional[:] = 0.0
            dt = 0.0
        self._holding = holding
        closed = cfg.mode == "closed" and dt > 0.0
        keep = closed and tensions is not None and cfg.min_tension > 0.0
        # C-contiguous float arrays (no copy where they are already): one compiled signature.
        measured = self._no_tensions if tensions is None else np.ascontiguousarray(tensions, dtype=np.float64)
        q = np.ascontiguousarray(q_plan, dtype=np.float64)
        plan = np.ascontiguousarray(tcp_plan, dtype=np.float64)
        pos = np.ascontiguousarray(tcp_pos, dtype=np.float64)
        mat = np.ascontiguousarray(tcp_mat, dtype=np.float64).reshape(3, 3)
        lengths = np.empty(len(self.offset))
        args = (self.law, self.state, q, plan, pos, mat, float(dt), closed, keep, measured, self._r)
        if tick(*args, False, lengths) == ROTATION_BEYOND_3_RAD:  # the robust log, then the same tick
            self._r[:] = kin.log_so3(plan[:3, :3] @ mat.T)
            tick(*args, True, lengths)
        self.last_command = self.state["w"][0].tolist()
        return lengths
