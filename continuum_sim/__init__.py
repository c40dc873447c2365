"""continuum_sim: MuJoCo simulation of a dual-arm cable-driven continuum robot.

Implements the robot of "Design and Collaborative Operation of a Dual-Arm Continuum
Robot" (Biomimetics 2023, 8, 4): discrete PCC kinematics, optimisation IK along
toolpaths, a generated MuJoCo model, and the collaborative sample-removal task.
"""

from .configio import ConfigError
from .geometry import ArmGeometry, Material, SectionGeometry, ToolGeometry
from .ik import IKOptions, IKResult, StepLimits, solve_ik, solve_path
from .kinematics import (
    cable_length_changes,
    cable_lengths,
    continuous_forward_kinematics,
    disk_frames,
    forward_kinematics,
    jacobian,
    motor_angles,
    straight_cable_lengths,
    tool_centre_pose,
)

__all__ = [
    "ArmGeometry",
    "ConfigError",
    "IKOptions",
    "IKResult",
    "Material",
    "SectionGeometry",
    "StepLimits",
    "ToolGeometry",
    "cable_length_changes",
    "cable_lengths",
    "continuous_forward_kinematics",
    "disk_frames",
    "forward_kinematics",
    "jacobian",
    "motor_angles",
    "solve_ik",
    "solve_path",
    "straight_cable_lengths",
    "tool_centre_pose",
]

__version__ = "0.1.0"
