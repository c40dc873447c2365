"""``PlanConfig``: how the task is planned (speeds, dwells, step limits, IK modes, path shapes, envelopes)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..configio import ConfigError, require_positive, require_range
from ..ik import IKOptions, StepLimits

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PlanConfig:
    """How the task is planned: speeds, dwells, step limits, IK modes, path shapes."""

    sample_rate_hz: float = 100.0
    cut_speed: float = 0.005  # m/s, feed along the kerf
    fast_speed: float = 0.040  # m/s, every other Cartesian move
    max_accel: float = 0.2  # m/s², trapezoidal speed profile of the tool point
    rotation_radius: float = 0.1  # m/rad: a tool rotation counts as this much path length for timing
    joint_speed_deg_s: float = 20.0  # joint-space transfers: bending-coordinate speed per section
    joint_accel_deg_s2: float = 40.0
    waypoint_spacing: float = 0.002  # m between IK-solved toolpath points
    dwell_initial: float = 0.5  # s
    dwell_close: float = 1.0  # s, gripper closing on the plate
    dwell_spin_up: float = 1.0  # s, spindle reaching speed before the approach
    dwell_final: float = 0.5  # s
    dwell_before_cut: float = 1.5  # s, the grinder settles at the cut start (in air) before feeding
    lead_in: float = 0.012  # m: the cut starts this far outside the front edge (> kerf_width/2)
    lead_out: float = 0.020  # m: and ends this far beyond the side edge, where the grinder waits while the sample is carried off
    approach_length: float = 0.020  # m: horizontal approach toward the front edge before the cut start
    # m: the gripper backs off this far from the grasp pose before the grasp (formerly 0.035;
    # in the plate plane 35 mm leave 2.2 mm of planned pad clearance at the transfer's end, 50 mm 14.6 mm)
    pregrasp_distance: float = 0.050
    # Direction of that back-off (and so of the straight grasp move): "plate_plane" = the tool
    # axis projected onto the plate's plane, so the open jaws slide in level with the plate
    # faces, their clearance constant; "tool_axis" = along the tilted tool axis (the former default:
    # the pads crossed the plate faces obliquely, and the joint transfer ending there drove a
    # pad 1.7 mm into the sample edge, docs/calibration.md "The gripper knock").
    pregrasp_direction: Literal["plate_plane", "tool_axis"] = "plate_plane"
    # m, world: sample carried away (stage 4), mostly sideways (-y) so it clears the grinder
    # housing that waits beyond the side edge, below the plate ((0.04, -0.03, -0.05) grazed it)
    carry_offset: tuple[float, float, float] = (0.02, -0.09, -0.03)
    return_offset: float = 0.004  # m: the grinder returns this far inside the freed sample area, clear of the kerf's outer wall
    q_left_initial_deg: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    q_right_initial_deg: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    grinder_phase: Literal["free", "planar"] = "free"  # the grinder's tool roll is free: 'axis' orientation
    gripper_phase: Literal["free", "planar"] = "free"  # the gripper needs 'full' orientation
    limits: StepLimits = field(default_factory=StepLimits)
    ik: IKOptions = field(default_factory=IKOptions)
    grinder_radius: float = 0.015  # m, collision envelope of the grinder housing (the cutter: kerf_width/2)
    grinder_cutter_length: float = 0.020  # m, the cutter's exposed length below the TCP (the rest is housing)
    gripper_radius: float = 0.012  # m, collision spheres of the gripper (palm, fingers, pads)
    gripper_half_width: float = 0.014  # m, offset of the outer gripper spheres along the tool x (open jaws)
    min_clearance: float = 0.003  # m: plans with less arm-to-arm clearance are refused
    progress: bool = False  # tqdm progress bars

    def __post_init__(self) -> None:
        require_range("sample_rate_hz", self.sample_rate_hz, 1.0, 10_000.0, low_inclusive=True)
        require_range("cut_speed", self.cut_speed, 0.0, 0.5)
        require_range("fast_speed", self.fast_speed, 0.0, 1.0)
        require_range("max_accel", self.max_accel, 0.0, 100.0)
        require_range("rotation_radius", self.rotation_radius, 0.0, 10.0, low_inclusive=True)
        require_range("joint_speed_deg_s", self.joint_speed_deg_s, 0.0, 3600.0)
        require_range("joint_accel_deg_s2", self.joint_accel_deg_s2, 0.0, 1e5)
        require_range("waypoint_spacing", self.waypoint_spacing, 1e-4, 0.05, low_inclusive=True)
        for name in ("dwell_initial", "dwell_close", "dwell_spin_up", "dwell_final", "dwell_before_cut"):
            require_range(name, getattr(self, name), 0.0, 600.0, low_inclusive=True)
        require_range("lead_in", self.lead_in, 0.0, 0.2)
        require_range("lead_out", self.lead_out, 0.0, 0.2)
        require_range("approach_length", self.approach_length, 0.0, 0.2, low_inclusive=True)
        require_range("pregrasp_distance", self.pregrasp_distance, 0.0, 0.3)
        if self.pregrasp_direction not in ("plate_plane", "tool_axis"):
            raise ConfigError("pregrasp_direction", f"must be 'plate_plane' or 'tool_axis' (got {self.pregrasp_direction!r})")
        require_range("return_offset", self.return_offset, 0.0, 0.05, low_inclusive=True)
        for i, v in enumerate(self.carry_offset):
            require_range(f"carry_offset[{i}]", v, -0.5, 0.5, low_inclusive=True)
        for name in ("q_left_initial_deg", "q_right_initial_deg"):
            q = getattr(self, name)
            if len(q) != 6:
                raise ConfigError(name, f"must have 6 entries (θ, φ per section; got {len(q)})")
            for k in range(3):
                require_range(f"{name}[{2 * k}]", q[2 * k], 0.0, 90.0, low_inclusive=True)
                require_range(f"{name}[{2 * k + 1}]", q[2 * k + 1], -360.0, 360.0, low_inclusive=True)
        for name in ("grinder_phase", "gripper_phase"):
            if getattr(self, name) not in ("free", "planar"):
                raise ConfigError(name, f"must be 'free' or 'planar' (got {getattr(self, name)!r})")
        require_positive("grinder_radius", self.grinder_radius)
        require_positive("gripper_radius", self.gripper_radius)
        require_range("grinder_cutter_length", self.grinder_cutter_length, 0.0, 0.5, low_inclusive=True)
        require_range("gripper_half_width", self.gripper_half_width, 0.0, 0.2, low_inclusive=True)
        require_range("min_clearance", self.min_clearance, -1.0, 1.0)

    def q_initial(self, arm: str) -> Array:
        return np.radians(self.q_left_initial_deg if arm == "left" else self.q_right_initial_deg)
