"""continuum_sim: MuJoCo simulation of a dual-arm cable-driven continuum robot.

Implements the robot of "Collaborative Continuum Robots for Remote Engineering Operations"
(Biomimetics 2023, 8(1), 4, doi:10.3390/biomimetics8010004): discrete PCC kinematics,
optimisation IK along toolpaths, a generated MuJoCo model, and the collaborative
sample-removal task.

Importing the package chooses MuJoCo's OpenGL backend (``glbackend.choose_gl_backend``),
once, before any module imports ``mujoco`` or ``dm_control``. The names below are loaded on
first use, so ``import continuum_sim.scenario.config`` stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .glbackend import choose_gl_backend

try:
    choose_gl_backend()
except ValueError:  # an unknown MUJOCO_GL: the CLI reports it in one line before any work
    pass

if TYPE_CHECKING:
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

_EXPORTS = {
    "ConfigError": "configio",
    "ArmGeometry": "geometry",
    "Material": "geometry",
    "SectionGeometry": "geometry",
    "ToolGeometry": "geometry",
    "IKOptions": "ik",
    "IKResult": "ik",
    "StepLimits": "ik",
    "solve_ik": "ik",
    "solve_path": "ik",
    "cable_length_changes": "kinematics",
    "cable_lengths": "kinematics",
    "continuous_forward_kinematics": "kinematics",
    "disk_frames": "kinematics",
    "forward_kinematics": "kinematics",
    "jacobian": "kinematics",
    "motor_angles": "kinematics",
    "straight_cable_lengths": "kinematics",
    "tool_centre_pose": "kinematics",
}

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
assert sorted(__all__) == sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'continuum_sim' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


__version__ = "0.1.0"
