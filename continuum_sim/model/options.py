"""Model fidelity and actuation options: how a geometry becomes a MuJoCo model."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Literal

from ..configio import ConfigError, require_int, require_positive, require_range
from ..geometry import ArmGeometry
from .friction_options import CableFrictionConfig


@dataclass(frozen=True)
class ModelOptions:
    """Options of the generated model; the physical robot itself lives in ``ArmGeometry``.

    ``segments_per_section`` = 0 keeps the physical segment count; another value
    resamples each section with that many joints while the per-joint stiffness scales as
    k = n·EI/L, so the section's response does not change.
    """

    # ball: MuJoCo ball joint, isotropic spring (mean bending stiffness, also in twist);
    # hinge_pair: x/y hinges with per-axis springs, rigid in twist (a universal joint);
    # hinge_triple: x/y/z hinges, the z spring is the segment's twist stiffness.
    joint: Literal["ball", "hinge_pair", "hinge_triple"] = "ball"
    segments_per_section: int = 0
    stiffness_scale: float = 1.0  # multiplies every flexure stiffness (the design sweep knob)
    # The segments' moment–rotation (docs/model.md, "Flexures beyond linear"): "linear" = the
    # joint springs alone; "nonlinear" = the springs plus the remainder of the geometrically
    # exact leaf model (compressed-leaf buckling, the joint's kinematics), a per-step plant
    # effect (plant/flexure.py); no effect on a rod backbone (it has no leaves).
    flexure_model: Literal["linear", "nonlinear"] = "linear"
    joint_damping: float = 0.2  # N·m·s/rad per physical joint (hinge + ball friction, *assumed*); scaled like stiffness
    joint_armature: float = 1e-5  # kg·m², numerical regulariser for light disks
    # --- Transmission (docs/plant.md): rope, motors. ---
    # "elastic": each cable is its own spring EA/L (rope modulus × area over its routed
    # length: lead + in-arm path), pulled by a motor whose position (a PI encoder loop
    # with speed and force limits, continuum_sim.plant.drive) is the actuator's control;
    # "lumped": the legacy single P-only servo of gain cable_kp standing for motor and cable.
    cable_model: Literal["elastic", "lumped"] = "elastic"
    rope_diameter: float = 1.0e-3  # m, nominal diameter of the steel wire rope (*assumed*, docs/plant.md)
    rope_modulus: float = 73.2e9  # Pa, effective modulus on the nominal area π d²/4: 7x7 302/304 stainless (Loos G factor)
    cable_lead_length: float = 0.25  # m, rope from the spool through the pack's guides to the arm's base plate (*assumed*)
    cable_max_force: float = 200.0  # N, motor force rating at the cable = stall torque / spool radius (2 N·m at 10 mm)
    motor_max_speed: float = 0.06  # m/s, motor no-load speed at the cable = spool speed × spool radius
    motor_kp: float = 40.0  # 1/s, encoder position loop: proportional gain (velocity command per metre of error)
    motor_ki: float = 400.0  # 1/s², encoder position loop: integral gain (removes the load droop)
    cable_kp: float = 3.0e4  # N/m, lumped model only: motor position-loop gain expressed at the cable
    cable_kv: float = 0.0  # N·s/m, velocity gain of the motor loop at the cable (tension-only; implicit under implicitfast)
    # The cable spring integrated linearly implicitly (backward Euler): taut cables get the
    # velocity term k·timestep that implicitfast treats implicitly. Without it the stiff EA/L
    # spring is unstable at the 4 ms step once a grasp pins the tip (docs/plant.md, "Tension chatter").
    cable_implicit_spring: bool = True
    # Divide `timestep` by the smallest whole n that keeps the stiffest cable's and the stiffest
    # flexure joint's k·h² within cable_elasticity.CABLE_STEP_LIMIT / JOINT_STEP_LIMIT (what the default
    # task was verified to run at). Stiff cables (≥ 5e5 N/m at 4 ms) and hinges above ×8
    # diverged at 4 ms; a whole n keeps every control tick a whole number of steps.
    # False: `timestep` as given.
    stable_step: bool = True
    cable_damping: float = 200.0  # N·s/m, viscous damping along each cable (motor loop + guides; passive, implicit)
    grinder_mass: float = 0.08  # kg; the spindle motor sits in the pack (flexible shaft)
    gripper_mass: float = 0.06  # kg
    timestep: float = 0.001
    integrator: Literal["implicitfast", "implicit", "Euler", "RK4"] = "implicitfast"
    jacobian: Literal["auto", "dense", "sparse"] = "auto"  # MuJoCo's constraint Jacobian storage
    impratio: float = 100.0  # friction-to-normal impedance ratio (elliptic cones): high = little frictional creep
    tendons: bool = True  # False: joints only (for benchmarks and pure-beam tests)
    # False: no gravity anywhere in the model (an attribution switch, docs/calibration.md:
    # what gravity alone costs the open loop). Static evaluations that set gravity per phase
    # (sweep gravity_sag) still do so on the compiled model.
    gravity: bool = True
    # How a scenario run evaluates the cables (plant/cable_path.py): "native" = fixed tendons
    # whose exact lengths and Jacobians a compiled kernel writes in the passive stage (the
    # spatial tendons' numbers to ~1e-15 m, a third less CPU per step); "spatial" = MuJoCo's
    # own spatial tendons (the plain path; what models/ holds and the video draws).
    cable_path: Literal["native", "spatial"] = "native"
    # Friction of the cables in the disk holes: capstan loss with stick/slip (plant/friction.py,
    # docs/friction.md); mu = 0 installs nothing.
    cable_friction: CableFrictionConfig = field(default_factory=CableFrictionConfig)

    def __post_init__(self) -> None:
        if self.joint not in ("ball", "hinge_pair", "hinge_triple"):
            raise ConfigError("joint", f"must be 'ball', 'hinge_pair' or 'hinge_triple' (got {self.joint!r})")
        require_int("segments_per_section", self.segments_per_section, 0, 200, hint=", 0 = physical count")
        require_range("stiffness_scale", self.stiffness_scale, 0.0, 1e4)
        if self.flexure_model not in ("linear", "nonlinear"):
            raise ConfigError("flexure_model", f"must be 'linear' or 'nonlinear' (got {self.flexure_model!r})")
        require_range("joint_damping", self.joint_damping, 0.0, 100.0, low_inclusive=True)
        require_range("joint_armature", self.joint_armature, 0.0, 1.0, low_inclusive=True)
        if self.cable_model not in ("elastic", "lumped"):
            raise ConfigError("cable_model", f"must be 'elastic' or 'lumped' (got {self.cable_model!r})")
        require_range("rope_diameter", self.rope_diameter, 0.0, 0.01)
        require_range("rope_modulus", self.rope_modulus, 0.0, 1e12)
        require_range("cable_lead_length", self.cable_lead_length, 0.0, 10.0, low_inclusive=True)
        require_positive("cable_max_force", self.cable_max_force)
        require_range("motor_max_speed", self.motor_max_speed, 0.0, 10.0)
        require_range("motor_kp", self.motor_kp, 0.0, 1e4)
        require_range("motor_ki", self.motor_ki, 0.0, 1e6, low_inclusive=True)
        require_positive("cable_kp", self.cable_kp)
        require_range("cable_kv", self.cable_kv, 0.0, 1e6, low_inclusive=True)
        require_range("cable_damping", self.cable_damping, 0.0, 1e6, low_inclusive=True)
        require_range("grinder_mass", self.grinder_mass, 0.0, 10.0)
        require_range("gripper_mass", self.gripper_mass, 0.0, 10.0)
        require_range("timestep", self.timestep, 0.0, 0.01)
        require_range("impratio", self.impratio, 1.0, 1000.0, low_inclusive=True)
        if self.jacobian not in ("auto", "dense", "sparse"):
            raise ConfigError("jacobian", f"must be one of auto, dense, sparse (got {self.jacobian!r})")
        if self.cable_path not in ("native", "spatial"):
            raise ConfigError("cable_path", f"must be 'native' or 'spatial' (got {self.cable_path!r})")
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
        raise ConfigError("model.segments_per_section", f"{n} segments make the disks overlap ({exc})") from None
