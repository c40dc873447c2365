"""The cables' elasticity as the model is built: rope stiffness, the stable step, the spring's implicit term.

Each cable is a steel wire rope of effective modulus E (on its nominal area A = π d²/4)
and routed length L = lead + in-arm path (spool → pack guides → base plate → holes →
anchor disk): a spring of stiffness k = E·A/L that only pulls. In the MuJoCo model it is
the cable's tension-only position actuator (``arm.py``): force = k·(x − l), clipped to
[−Fmax, 0], with l the tendon length and x the motor position (``plant/drive.py``).
These are the values the builders and the run's set-up need; the motors that move x at
run time are ``plant.drive``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..geometry import ArmGeometry
from ..kinematics import straight_cable_lengths
from .options import ModelOptions, model_geometry

Array = NDArray[np.float64]


def rope_area(options: ModelOptions) -> float:
    """Nominal area π d²/4 (m²) of the rope: the area the effective modulus is quoted on."""
    return math.pi * options.rope_diameter**2 / 4.0


def rope_axial_stiffness(options: ModelOptions) -> float:
    """E·A (N) of the rope."""
    return options.rope_modulus * rope_area(options)


def routed_lengths(geometry: ArmGeometry, options: ModelOptions, in_arm: Array | None = None) -> Array:
    """(n_cables,) length of rope between spool and anchor: lead + in-arm path (straight arm by default)."""
    if in_arm is None:
        in_arm = straight_cable_lengths(model_geometry(geometry, options))
    return options.cable_lead_length + np.asarray(in_arm, dtype=float)


def cable_stiffness(geometry: ArmGeometry, options: ModelOptions, in_arm: Array | None = None) -> Array:
    """(n_cables,) axial stiffness (N/m) of every cable: EA/L, or the lumped cable_kp.

    Distal cables run through the proximal sections as well, so they are longer and softer.
    """
    n = 3 * geometry.n_sections
    gain = np.repeat([s.cable_gain_scale for s in geometry.sections], 3)  # per-section calibration
    if options.cable_model == "lumped":
        return gain * np.full(n, float(options.cable_kp))
    return gain * rope_axial_stiffness(options) / routed_lengths(geometry, options, in_arm)


# N·s²/m: the largest k·h² of an arm's stiffest cable verified to run the whole default task
# (rope d = 2.08 mm: proximal cables 5.4e5 N/m at the 4 ms step, the task completes or fails
# by name); d = 2.6 mm (8.5e5 N/m, k·h² = 13.5) and 3.7 mm (1.7e6 N/m) diverged at 4 ms and
# run at 2 ms (docs/plant.md, "Cable stiffness 1e4–1e6 N/m"). The shipped rope: 2.0.
CABLE_STEP_LIMIT = 8.6


# N·m·s²/rad: the largest k·h² of the stiffest flexure joint verified to run the whole default
# task (hinges ×8 at 4 ms: 91.9 N·m/rad, 1.47e-3); ×11.3 (130 N·m/rad, 2.1e-3) diverged at 4 ms
# in the task and in the static sag evaluation, ×16 runs at 2 ms (named failure, not divergence).
# Joint springs are explicit under implicitfast, as the cable spring was (docs/plant.md).
JOINT_STEP_LIMIT = 1.5e-3


def stiffest_joint(geometry: ArmGeometry, options: ModelOptions) -> float:
    """The largest flexure-joint spring (N·m/rad) of the model (0 for the rod backbone)."""
    from .stiffness import joint_stiffnesses

    if geometry.backbone == "rod":
        return 0.0
    model_geom = model_geometry(geometry, options)
    largest = 0.0
    for index, section in enumerate(model_geom.sections):
        kx, ky, kz = joint_stiffnesses(geometry, index, section.n_segments, options.stiffness_scale)
        twist = kz if options.joint == "hinge_triple" and math.isfinite(kz) else 0.0
        largest = max(largest, kx, ky, twist)
    return largest


def stable_timestep(geometry: ArmGeometry, options: ModelOptions) -> float:
    """The physics step (s): ``options.timestep`` divided by the smallest whole n with
    k·(h/n)² within its verified limit for the stiffest cable (EA/L or the lumped gain,
    CABLE_STEP_LIMIT) and the stiffest flexure joint (JOINT_STEP_LIMIT)."""
    h = float(options.timestep)
    if not options.stable_step:
        return h
    ratio = stiffest_joint(geometry, options) * h * h / JOINT_STEP_LIMIT
    if options.tendons:
        ratio = max(ratio, float(np.max(cable_stiffness(geometry, options))) * h * h / CABLE_STEP_LIMIT)
    n = max(1, math.ceil(math.sqrt(ratio) - 1e-9))
    return h / n


def implicit_spring_step(options: ModelOptions) -> float:
    """h (s) of the cable spring's backward-Euler velocity term k·h, or 0 when it is off."""
    return float(options.timestep) if options.cable_implicit_spring else 0.0


def cable_velocity_gain(stiffness: float, options: ModelOptions) -> float:
    """The cable actuator's velocity gain (N·s/m) while taut: the motor loop's cable_kv plus k·h.

    Backward Euler on the spring, T_{n+1} = k·(x − l_{n+1}) ≈ k·(x − l_n) − k·h·l̇_{n+1}: the
    term −k·h·l̇ is an actuator velocity bias, which MuJoCo's implicitfast integrator treats
    implicitly. It is the integrator's numerical damping of the stiff spring (it vanishes as
    h → 0), not a physical damper; without it the explicit spring k·h² exceeds what the
    distal disks' mass and the cable's damping can carry once a grasp pins the tip, and the
    4 ms step rings at ~25 Hz (docs/plant.md, "Tension chatter").
    """
    return float(options.cable_kv) + float(stiffness) * implicit_spring_step(options)


def pretension_offsets(geometry: ArmGeometry, options: ModelOptions, pretension: float) -> Array:
    """(n_cables,) motor set-point offsets (m) that give ``pretension`` (plus each section's
    ``extra_pretension``) at the planned shape: T/k."""
    extra = np.repeat([s.extra_pretension for s in geometry.sections], 3)
    return (float(pretension) + extra) / cable_stiffness(geometry, options)
