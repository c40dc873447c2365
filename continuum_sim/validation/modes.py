"""Bending modes of one cable-held section: MuJoCo linearisation against a beam reference.

Model: one section exactly as ``build_single_arm_model`` builds it (disks, flexure joints,
its three cables and their actuators), held: each actuator's control fixed at the straight
tendon length (the motors stop, the ropes stay elastic, no pretension), gravity off, all
damping zeroed so that the frequencies are the undamped ones a beam model gives; each rope carries a
small pretension (``PRETENSION``) so that it is taut, not on its slack kink.
``mujoco.mjd_transitionFD`` linearises one step (at ``LINEARISATION_STEP``, not the
scenario's 4 ms, whose Nyquist limit is 125 Hz); the eigenvalues μ of the transition
matrix give ω = |arg μ|/Δt. Bending modes are told from twist modes by the tip's lateral
motion, and come in x/y pairs (the section is isotropic); a pair's mean is reported.

Reference: a clamped Rayleigh beam (Euler–Bernoulli bending, rotary inertia) of the
section's EI (``model.stiffness``), the disks' mass μ = m/p and rotary inertia J/p per
length, the tip disk's outer half as a tip mass m/2 and inertia J/2 (the disk stack's
continuum limit, ``section.SectionBeam``), plus the held cables: cable c at hole angle φ_c
shortens by r·Θ·cos φ_c when the section's tip turns by Θ about an axis normal to φ_c, so
the three ropes (stiffness k_c = E_rope·A/(lead + L), from the plant options) act as one
rotational spring k_Θ = Σ k_c r² cos² φ_c = (3/2)·k_c·r² between the tip slope and the
ground. Solved by 120 Hermite beam elements (converged to < 1e-5).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..geometry import ArmGeometry
from ..model.options import ModelOptions
from .section import section_beam, single_section_geometry

Array = NDArray[np.float64]

# N per rope while held: enough to keep every rope taut through the linearisation, small
# enough that its compressive effect on the disk chain (~3T·p/4 per joint against
# k = EI/p) stays under 1 % of the joint stiffness.
PRETENSION = 2.0
# s: the step of the linearised one-step map. arg μ/Δt reads the continuous frequency only
# while ωΔt ≪ 1 (and cannot exceed the Nyquist limit 1/(2Δt): 125 Hz at the scenario's 4 ms);
# at 0.1 ms the map's frequency error for a 100 Hz mode is < 0.1 %. ``None``: the model's own step.
LINEARISATION_STEP = 1e-4


def beam_frequencies(
    ei: float,
    mass_per_length: float,
    length: float,
    *,
    rotary_inertia_per_length: float = 0.0,
    tip_mass: float = 0.0,
    tip_inertia: float = 0.0,
    tip_rotational_spring: float = 0.0,
    elements: int = 120,
    count: int = 2,
) -> Array:
    """Lowest ``count`` natural frequencies (Hz) of a clamped-free beam by Hermite finite elements."""
    from scipy.linalg import eigh

    h = length / elements
    ke = (
        ei
        / h**3
        * np.array(
            [
                [12, 6 * h, -12, 6 * h],
                [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                [-12, -6 * h, 12, -6 * h],
                [6 * h, 2 * h * h, -6 * h, 4 * h * h],
            ]
        )
    )
    me = (
        mass_per_length
        * h
        / 420.0
        * np.array(
            [
                [156, 22 * h, 54, -13 * h],
                [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                [54, 13 * h, 156, -22 * h],
                [-13 * h, -3 * h * h, -22 * h, 4 * h * h],
            ]
        )
    )
    # rotary inertia (consistent, from the slope field)
    mr = (
        rotary_inertia_per_length
        / (30.0 * h)
        * np.array([[36, 3 * h, -36, 3 * h], [3 * h, 4 * h * h, -3 * h, -h * h], [-36, -3 * h, 36, -3 * h], [3 * h, -h * h, -3 * h, 4 * h * h]])
    )
    n = 2 * (elements + 1)
    k = np.zeros((n, n))
    m = np.zeros((n, n))
    for e in range(elements):
        idx = slice(2 * e, 2 * e + 4)
        k[idx, idx] += ke
        m[idx, idx] += me + mr
    m[-2, -2] += tip_mass
    m[-1, -1] += tip_inertia
    k[-1, -1] += tip_rotational_spring
    k, m = k[2:, 2:], m[2:, 2:]  # clamp: w = w' = 0 at s = 0
    omega2 = eigh(k, m, eigvals_only=True, subset_by_index=[0, count - 1])
    return np.sqrt(omega2) / (2.0 * math.pi)


def reference_cable_stiffness(options: ModelOptions, in_arm_length: float) -> float:
    """k_c (N/m) of one held rope: E·πd²/4 over lead + in-arm length (``cable_kp`` when lumped)."""
    if options.cable_model == "lumped":
        return float(options.cable_kp)
    area = math.pi * options.rope_diameter**2 / 4.0
    return options.rope_modulus * area / (options.cable_lead_length + in_arm_length)


@dataclass(frozen=True)
class ModeComparison:
    section: int
    joint: str
    model: tuple[float, ...]  # Hz, bending pairs' means, lowest first
    reference: tuple[float, ...]
    cable_spring: float  # N·m/rad, k_Θ of the reference

    def errors_pct(self) -> list[float]:
        return [100.0 * (m / r - 1.0) for m, r in zip(self.model, self.reference)]


def model_bending_frequencies(
    geometry: ArmGeometry, options: ModelOptions, count: int = 2, pretension: float = PRETENSION, timestep: float | None = LINEARISATION_STEP
) -> Array:
    """Lowest ``count`` bending frequencies (Hz) of the held, undamped section (mjd_transitionFD)."""

    import mujoco

    from ..model.arm import build_single_arm_model

    root = build_single_arm_model(geometry, options, tool="none", gravity=False)
    m = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    if timestep is not None:
        m.opt.timestep = timestep
    m.dof_damping[:] = 0.0
    m.tendon_damping[:] = 0.0
    m.actuator_biasprm[:, 2] = 0.0  # position actuators' velocity gain (kv)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    # hold: each rope at a small pretension (a tension-only actuator at exactly zero force
    # sits on its slack kink and the linearisation would see half its stiffness)
    for a in range(m.nu):
        d.ctrl[a] = d.actuator_length[a] - pretension / m.actuator_gainprm[a, 0]
    mujoco.mj_forward(m, d)
    nv, na = m.nv, m.na
    a_mat = np.zeros((2 * nv + na, 2 * nv + na))
    mujoco.mjd_transitionFD(m, d, 1e-6, True, a_mat, None, None, None)
    mu, vec = np.linalg.eig(a_mat)
    omega = np.abs(np.angle(mu)) / m.opt.timestep
    tip = m.nbody - 1
    jacp, jacr = np.zeros((3, nv)), np.zeros((3, nv))
    mujoco.mj_jacBody(m, d, jacp, jacr, tip)
    radius = geometry.sections[-1].disk_diameter / 2.0
    freqs: list[float] = []
    for w, v in zip(omega, vec.T):
        if w <= 1e-6:
            continue
        q = v[:nv]
        lateral = np.linalg.norm(jacp[:2] @ q)
        twist = abs(jacr[2] @ q) * radius
        if lateral > twist:
            freqs.append(w / (2.0 * math.pi))
    unique = np.unique(np.round(np.sort(freqs), 6))
    # x/y pairs (and ± conjugates collapse in unique): cluster within 1 %
    clusters: list[list[float]] = []
    for f in unique:
        if clusters and f <= clusters[-1][0] * 1.01:
            clusters[-1].append(f)
        else:
            clusters.append([f])
    return np.array([np.mean(c) for c in clusters[:count]])


def compare_section_modes(geometry: ArmGeometry, section: int, options: ModelOptions, count: int = 2, timestep: float | None = LINEARISATION_STEP) -> ModeComparison:
    single = single_section_geometry(geometry, section)
    beam = section_beam(single, 0, options)
    sec = single.sections[0]
    k_c = reference_cable_stiffness(options, sec.length)
    angles = sec.cable_angles
    k_theta = float(np.sum(k_c * geometry.cable_hole_radius**2 * np.cos(angles) ** 2)) if options.tendons else 0.0
    ref = beam_frequencies(
        beam.ei,
        beam.disk_mass / beam.pitch,
        beam.length,
        rotary_inertia_per_length=beam.disk_inertia / beam.pitch,
        tip_mass=beam.disk_mass / 2.0,
        tip_inertia=beam.disk_inertia / 2.0,
        tip_rotational_spring=k_theta,
        count=count,
    )
    model = model_bending_frequencies(single, options, count, timestep=timestep)
    return ModeComparison(section, options.joint, tuple(float(f) for f in model), tuple(float(f) for f in ref), k_theta)


def without_cables(options: ModelOptions) -> ModelOptions:
    return dataclasses.replace(options, tendons=False)
