"""The spindle drive: the grinder's PI speed loop, its anti-windup and stall protection.

The spindle is a MuJoCo velocity actuator (``model/tools.py``): it supplies
``kv·(ctrl − ω)`` clipped to ±``max_torque``, the P half of the loop. ``SpindleDrive`` adds
the I half, ``∫ki·e dt``, by raising the set-point (``ctrl = ω_ref + I/kv``), and stops
integrating while the drive sits at its torque limit. A stall is a commanded spindle
turning slower than ``stall_fraction·ω_ref`` for ``stall_time``: the drive then trips
(ctrl 0, like a motor controller's stall protection) until the command returns to zero.

It is the one writer of the spindle actuator's ``ctrl``: ``command`` once per control tick
(the set-point, P only) and, where a per-physics-step hook runs it (the cutter's observer),
``step`` before every physics step (the PI loop). The cutter only reads whether it is
stalled and loads the spindle joint with its cutting torque (``qfrc_applied``).
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from ..model.scene_options import ToolOptions
from ..model.tools import GRINDER, SPINDLE_JOINT
from .jit import jit

# The drive's options and state in one record (``SpindleDrive.record``): what the compiled
# loop reads and writes.
SPINDLE_STATE = np.dtype([
    ("kv", "f8"), ("ki", "f8"), ("max_torque", "f8"), ("stall_fraction", "f8"), ("stall_time", "f8"),
    ("max_speed", "f8"),
    ("integral", "f8"),  # N·m, the I term's torque
    ("stalled", "f8"),  # 1: the drive tripped
    ("low", "f8"),  # 1: the speed is below the stall fraction since ``low_since``
    ("low_since", "f8"),  # s
])


@jit
def control(record: np.ndarray, reference: float, speed: float, time: float, dt: float) -> tuple[float, bool]:
    """The actuator set-point from the commanded and measured speed, and whether a stall tripped now."""
    s = record[0]
    if reference <= 0.0:
        s.integral = 0.0
        s.stalled = 0.0
        s.low = 0.0
        s.low_since = 0.0
        return 0.0, False
    if s.stalled != 0.0:
        return 0.0, False
    error = reference - speed
    torque = s.kv * error + s.integral
    saturated = abs(torque) >= s.max_torque and torque * error > 0
    if not saturated:
        s.integral = min(max(s.integral + s.ki * error * dt, -s.max_torque), s.max_torque)
    if speed < s.stall_fraction * reference:
        if s.low == 0.0:
            s.low = 1.0
            s.low_since = time
        if time - s.low_since >= s.stall_time:
            s.stalled = 1.0
            return 0.0, True
    else:
        s.low = 0.0
        s.low_since = 0.0
    return min(max(reference + s.integral / s.kv, 0.0), s.max_speed), False


@jit
def step(record: np.ndarray, qvel: np.ndarray, ctrl: np.ndarray, dof: int, actuator: int, reference: float,
          time: float, dt: float) -> bool:
    """``control`` on MuJoCo's buffers: reads the spindle's speed, writes its ctrl; True if a stall tripped."""
    value, tripped = control(record, reference, qvel[dof], time, dt)
    ctrl[actuator] = value
    return tripped



class SpindleDrive:
    """The spindle's speed loop on one model's grinder (see module doc); ``events`` lists
    ``(time, "stall", speed)``."""

    def __init__(self, model: mujoco.MjModel, tools: ToolOptions, arm: str = "left") -> None:
        name = f"{arm}/{GRINDER}/{SPINDLE_JOINT}"
        self.actuator = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name))
        joint = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name))
        if self.actuator < 0 or joint < 0:
            raise ValueError(f"model has no spindle {name!r}")
        self.dof = int(model.jnt_dofadr[joint])
        self.record = np.zeros(1, SPINDLE_STATE)
        r = self.record[0]
        r["kv"], r["ki"], r["max_torque"] = tools.spindle_kv, tools.spindle_ki, tools.spindle_max_torque
        r["stall_fraction"], r["stall_time"] = tools.spindle_stall_fraction, tools.spindle_stall_time
        r["max_speed"] = tools.spindle_max_speed
        self.events: list[tuple[float, str, float]] = []
        self._data: Any = None
        self._buffers: tuple[Any, Any] = (None, None)

    @property
    def integral(self) -> float:
        """N·m, the I term's torque."""
        return float(self.record["integral"][0])

    @property
    def stalled(self) -> bool:
        return bool(self.record["stalled"][0] != 0.0)

    @property
    def low_since(self) -> float | None:
        """When the speed last fell below the stall fraction (None: it is not below)."""
        return float(self.record["low_since"][0]) if self.record["low"][0] != 0.0 else None

    def reset(self) -> None:
        for name in ("integral", "stalled", "low", "low_since"):
            self.record[name] = 0.0
        self.events.clear()

    def speed(self, data: mujoco.MjData) -> float:
        """The measured spindle speed (rad/s)."""
        return float(data.qvel[self.dof])

    def control(self, reference: float, speed: float, time: float, dt: float) -> float:
        """The actuator set-point for the next step from the commanded and measured speed."""
        value, tripped = control(self.record, float(reference), float(speed), float(time), float(dt))
        if tripped:
            self.events.append((float(time), "stall", float(speed)))
        return float(value)

    def command(self, data: mujoco.MjData, reference: float) -> None:
        """Once per control tick: the commanded speed as the set-point (the velocity actuator's P loop)."""
        data.ctrl[self.actuator] = reference

    def step(self, data: mujoco.MjData, reference: float, dt: float) -> None:
        """Before one physics step: the PI loop's set-point into ``ctrl`` (stall events appended)."""
        if data is not self._data:
            self._data, self._buffers = data, (data.qvel, data.ctrl)
        qvel, ctrl = self._buffers
        time = data.time
        if step(self.record, qvel, ctrl, self.dof, self.actuator, reference, time, dt):
            self.events.append((float(time), "stall", float(qvel[self.dof])))
