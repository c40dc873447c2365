"""Model fidelity and actuation options: how a geometry becomes a MuJoCo model."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

from ..configio import ConfigError, require_int, require_positive, require_range
from ..geometry import ArmGeometry


@dataclass(frozen=True)
class ModelOptions:
    """Options of the generated model; the physical robot itself lives in ``ArmGeometry``.

    ``segments_per_section`` = 0 keeps the physical segment count; another value
    resamples each section with that many joints while the per-joint stiffness scales as
    k = n·EI/L, so the section's response does not change.
    """

    joint: Literal["ball", "hinge_pair"] = "ball"
    segments_per_section: int = 0
    stiffness_scale: float = 1.0  # multiplies every flexure stiffness (the design sweep knob)
    joint_damping: float = 0.2  # N·m·s/rad per physical joint (hinge + ball friction, *assumed*); scaled like stiffness
    joint_armature: float = 1e-5  # kg·m², numerical regulariser for light disks
    cable_max_force: float = 150.0  # N, Fmax of each tension-only cable actuator
    cable_kp: float = 3.0e4  # N/m, motor position-loop gain expressed at the cable
    cable_kv: float = 0.0  # N·s/m, velocity gain of the motor loop at the cable (explicit, tension-only)
    cable_damping: float = 200.0  # N·s/m, viscous damping along each cable (motor loop + guides; passive, implicit)
    grinder_mass: float = 0.08  # kg; the spindle motor sits in the pack (flexible shaft)
    gripper_mass: float = 0.06  # kg
    timestep: float = 0.001
    integrator: Literal["implicitfast", "implicit", "Euler", "RK4"] = "implicitfast"
    jacobian: Literal["auto", "dense", "sparse"] = "auto"  # MuJoCo's constraint Jacobian storage
    impratio: float = 100.0  # friction-to-normal impedance ratio (elliptic cones): high = little frictional creep
    tendons: bool = True  # False: joints only (for benchmarks and pure-beam tests)

    def __post_init__(self) -> None:
        if self.joint not in ("ball", "hinge_pair"):
            raise ConfigError("joint", f"must be 'ball' or 'hinge_pair' (got {self.joint!r})")
        require_int("segments_per_section", self.segments_per_section, 0, 200, hint=", 0 = physical count")
        require_range("stiffness_scale", self.stiffness_scale, 0.0, 1e4)
        require_range("joint_damping", self.joint_damping, 0.0, 100.0, low_inclusive=True)
        require_range("joint_armature", self.joint_armature, 0.0, 1.0, low_inclusive=True)
        require_positive("cable_max_force", self.cable_max_force)
        require_positive("cable_kp", self.cable_kp)
        require_range("cable_kv", self.cable_kv, 0.0, 1e6, low_inclusive=True)
        require_range("cable_damping", self.cable_damping, 0.0, 1e6, low_inclusive=True)
        require_range("grinder_mass", self.grinder_mass, 0.0, 10.0)
        require_range("gripper_mass", self.gripper_mass, 0.0, 10.0)
        require_range("timestep", self.timestep, 0.0, 0.01)
        require_range("impratio", self.impratio, 1.0, 1000.0, low_inclusive=True)
        if self.jacobian not in ("auto", "dense", "sparse"):
            raise ConfigError("jacobian", f"must be one of auto, dense, sparse (got {self.jacobian!r})")
        if self.integrator not in ("implicitfast", "implicit", "Euler", "RK4"):
            raise ConfigError("integrator", f"must be one of implicitfast, implicit, Euler, RK4 (got {self.integrator!r})")


def model_geometry(geometry: ArmGeometry, options: ModelOptions) -> ArmGeometry:
    """The geometry the model is built on (segment count resampled when asked).

    Kinematics evaluated on this geometry is exact for the generated model.
    """
    if options.segments_per_section == 0:
        return geometry
    n = options.segments_per_section
    sections = tuple(dataclasses.replace(s, n_segments=n) for s in geometry.sections)
    try:
        return dataclasses.replace(geometry, sections=sections)
    except ConfigError as exc:
        raise ConfigError("segments_per_section", f"{n} segments make the disks overlap ({exc})") from None
