"""Outer-loop gains derived from the plant (docs/plant.md, "Outer-loop gains from the plant").

The closed loop (``control.ArmController``) integrates the tool-pose error, mapped to
bending coordinates w (u, v per section) through the PCC Jacobian, into a correction of
the *commanded* shape. The arm does not take the commanded shape: its cables stretch.
Statically, with the motors at their set-points (their PI loops remove the load droop),

    (K_flex + K_cab) w = K_cab w_cmd + τ_load,    K_cab = Aᵀ diag(k) A,

with K_flex = diag(EI_s/L_s) (each section's hinge chain, joints in series: the per-joint
stiffness over the joints), A = −∂l/∂w the cables' moment arms (≈ r per cable and
section it passes, so K_cab ≈ (3/2)·k·r² per section for three cables at radius r, plus
what the distal cables add), k = EA/L per cable. The static transmission from command to
shape is therefore

    R = ∂w/∂w_cmd = (K_flex + K_cab)⁻¹ K_cab,    R⁻¹ = I + K_cab⁻¹ K_flex.

An integral loop ċ = G·Δw (Δw: the pose error in bending coordinates) on a plant
w = R (w_plan + c) + w_load closes with the error dynamics ė = −R G e. Choosing

    G = ω_c · R⁻¹ = ω_c · (I + K_cab⁻¹ K_flex)

puts every direction's pole at ω_c whatever the hinge stiffness, cable stiffness or
section: the loop's bandwidth is a design-independent number. It must stay below the
structure's own dynamics, the arm with its cables held by the motors (linearised in
MuJoCo at the straight pose with the pre-tension and the tool's mass): ω_c is capped at
``mode_fraction``·ω₁, ω₁ the lowest undamped natural frequency (0.5 by default, an
octave below it), so a stiffer arm (higher ω₁) may be driven faster and a softer or
heavier one is slowed down.

For reference the loop's stability bound on a single mode: an integrator ω_c/s around
1/(1 + 2ζs/ω₁ + s²/ω₁²) is stable only for ω_c < 2ζ₁ω₁ (Routh on s³/ω₁² + 2ζs²/ω₁ + s +
ω_c). With the first mode's modal damping (``ArmModes.modal_decay`` = ζ₁ω₁) that bound is
13.8 rad/s at the default hinges and 10.9 at ×8; it assumes the mode takes the whole
loop gain, and ω_c = 12 at the default ran without ringing (docs/plant.md), so it is
reported, not enforced.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from . import kinematics as kin
from .geometry import ArmGeometry

Array = NDArray[np.float64]


def section_flexure_stiffness(geometry: ArmGeometry, scale: float | Array = 1.0) -> Array:
    """(n_sections,) bending stiffness of each section in its bending coordinates (N·m/rad); ``scale``: one or per section.

    n joints in series of per-joint stiffness k_j = n·EI/L each carry θ/n: K = k_j/n = EI/L.
    """
    from .model.stiffness import joint_stiffness

    scales = np.broadcast_to(np.asarray(scale, dtype=float), (geometry.n_sections,))
    return np.array([joint_stiffness(geometry, s, 1, float(scales[s])) for s in range(geometry.n_sections)])


def cable_moment_arms(geometry: ArmGeometry, w: Array | None = None, h: float = 1e-6) -> Array:
    """(n_cables, 2·n_sections) A = −∂l/∂w at ``w`` (default straight), central differences of the PCC cable lengths."""
    n = 2 * geometry.n_sections
    w0 = np.zeros(n) if w is None else np.asarray(w, dtype=float)
    d = h * np.eye(n)
    return np.asarray(-(kin.cable_lengths_bending(geometry, w0 + d) - kin.cable_lengths_bending(geometry, w0 - d)).T / (2.0 * h))


def stiffness_matrices(
    geometry: ArmGeometry, cable_k: Array, scale: float | Array = 1.0, w: Array | None = None
) -> tuple[Array, Array]:
    """(K_flex, K_cab), each (2n, 2n) in bending coordinates (N·m/rad)."""
    k_flex = np.repeat(section_flexure_stiffness(geometry, scale), 2)
    A = cable_moment_arms(geometry, w)
    k = np.broadcast_to(np.asarray(cable_k, dtype=float), (A.shape[0],))
    return np.diag(k_flex), A.T @ (k[:, None] * A)


def transmission(geometry: ArmGeometry, cable_k: Array, scale: float | Array = 1.0, w: Array | None = None) -> Array:
    """R = (K_flex + K_cab)⁻¹ K_cab: achieved bend per commanded bend, statically (2n × 2n)."""
    k_flex, k_cab = stiffness_matrices(geometry, cable_k, scale, w)
    return np.asarray(np.linalg.solve(k_flex + k_cab, k_cab), dtype=float)


def inverse_transmission(geometry: ArmGeometry, cable_k: Array, scale: float | Array = 1.0, w: Array | None = None) -> Array:
    """R⁻¹ = I + K_cab⁻¹ K_flex (2n × 2n)."""
    k_flex, k_cab = stiffness_matrices(geometry, cable_k, scale, w)
    return np.eye(len(k_flex)) + np.linalg.solve(k_cab, k_flex)


@dataclass(frozen=True)
class ArmModes:
    """The linearised arm's slowest dynamics (rad/s)."""

    first_mode: float  # ω₁: lowest undamped natural frequency, √ of the smallest eigenvalue of M⁻¹K
    modal_decay: float  # ζ₁ω₁ = ½ φ₁ᵀDφ₁ / φ₁ᵀMφ₁ of the first undamped mode φ₁: the integral loop is stable below 2ζ₁ω₁
    decay: float  # σ₁: smallest decay rate |Re λ| of the damped arm (state matrix [[0, I], [−M⁻¹K, −M⁻¹D]])


def arm_modes(
    geometry: ArmGeometry, options, pretension: float, tool_mass: float = 0.0, tool_length: float = 0.0, h: float = 1e-6
) -> ArmModes:
    """ω₁ and σ₁ of one arm, straight, its cables at the pre-tension and its motors held.

    Linearised MuJoCo model of the arm alone (no gravity), the tool a point mass
    ``tool_mass`` half ``tool_length`` beyond the last disk: K = −∂f/∂q and D = −∂f/∂q̇
    with f = qfrc_passive + qfrc_actuator (hinge springs and dampers, the cables as the
    position actuators' springs, their damping and the implicit spring's k·h term), by
    central differences; M = mj_fullM.
    """
    return _arm_modes_cached(geometry, options, float(pretension), float(tool_mass), float(tool_length), float(h))


def first_mode(
    geometry: ArmGeometry, options, pretension: float, tool_mass: float = 0.0, tool_length: float = 0.0
) -> float:
    """ω₁ (rad/s), see ``arm_modes``."""
    return arm_modes(geometry, options, pretension, tool_mass, tool_length).first_mode


@functools.lru_cache(maxsize=16)
def _arm_modes_cached(
    geometry: ArmGeometry, options, pretension: float, tool_mass: float, tool_length: float, h: float
) -> ArmModes:
    import mujoco

    from .model import names
    from .model.arm import build_single_arm_model
    from .model.cable_elasticity import cable_stiffness
    from .model.options import model_geometry

    root = build_single_arm_model(geometry, options, gravity=False)
    if tool_mass > 0.0:
        tip = root.find("site", names.scoped(names.SINGLE_ARM, names.TOOL_MOUNT_SITE)).parent
        tip.add("geom", type="sphere", size=(0.005,), pos=(0.0, 0.0, tool_length / 2.0), mass=tool_mass, contype=0, conaffinity=0)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    data = mujoco.MjData(model)
    if model.nu:
        straight = kin.straight_cable_lengths(model_geometry(geometry, options))
        data.ctrl[:] = straight - pretension / cable_stiffness(geometry, options)
    nv = model.nv

    def force(dq: Array, dv: Array) -> Array:
        qpos = model.qpos0.copy()
        mujoco.mj_integratePos(model, qpos, dq, 1.0)
        data.qpos[:] = qpos
        data.qvel[:] = dv
        mujoco.mj_forward(model, data)
        return data.qfrc_passive + data.qfrc_actuator

    K, D, zero = np.empty((nv, nv)), np.empty((nv, nv)), np.zeros(nv)
    for j in range(nv):
        d = np.zeros(nv)
        d[j] = h
        K[:, j] = -(force(d, zero) - force(-d, zero)) / (2.0 * h)
        D[:, j] = -(force(zero, d) - force(zero, -d)) / (2.0 * h)
    force(zero, zero)
    M = np.zeros((nv, nv))
    mujoco.mj_fullM(model, data, M)
    # Generalised symmetric eigenproblem K φ = ω² M φ (scipy returns M-normalised φ).
    from scipy.linalg import eigh

    eig, vectors = eigh(0.5 * (K + K.T), M)
    positive = np.flatnonzero(eig > 0.0)
    omega1, modal = 0.0, 0.0
    if positive.size:
        i = positive[np.argmin(eig[positive])]
        omega1 = float(math.sqrt(eig[i]))
        phi = vectors[:, i]  # M-normalised mode shape
        modal = 0.5 * float(phi @ D @ phi) / float(phi @ M @ phi)
    state = np.block([[np.zeros((nv, nv)), np.eye(nv)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])
    decay = -np.linalg.eigvals(state).real
    decay = decay[decay > 0.0]
    return ArmModes(omega1, modal, float(decay.min()) if decay.size else 0.0)


@dataclass(frozen=True)
class PlantGain:
    """The derived outer-loop gain of one arm and the quantities it came from."""

    matrix: Array  # (2n, 2n) G = ω_c·R⁻¹, 1/s
    crossover: float  # ω_c actually used (after the mode cap), rad/s
    requested: float  # ω_c asked for (control.outer_gain in plant mode), rad/s
    first_mode: float  # ω₁, rad/s
    modal_decay: float  # ζ₁ω₁, rad/s (the integral loop's single-mode stability bound is 2ζ₁ω₁)
    decay: float  # σ₁, rad/s: the damped arm's slowest decay rate
    rho: Array  # (2n,) eigenvalues of R (static transmission per direction), ascending

    @property
    def capped(self) -> bool:
        return self.crossover < self.requested


def plant_gain(
    geometry: ArmGeometry,
    options,
    crossover: float,
    mode_fraction: float,
    pretension: float,
    cable_k: Array | None = None,
    tool_mass: float = 0.0,
    tool_length: float = 0.0,
) -> PlantGain:
    """G = min(ω_c, mode_fraction·ω₁)·R⁻¹ for one arm (see the module docstring)."""
    from .model.cable_elasticity import cable_stiffness

    k = cable_stiffness(geometry, options) if cable_k is None else np.asarray(cable_k, dtype=float)
    scale = options.stiffness_scale  # each section's own factor (arm.sections.k.stiffness_scale) is in its joint stiffness
    r_inv = inverse_transmission(geometry, k, scale)
    rho = np.sort(np.linalg.eigvals(np.linalg.inv(r_inv)).real)
    modes = arm_modes(geometry, options, pretension, tool_mass, tool_length)
    used = min(crossover, mode_fraction * modes.first_mode) if modes.first_mode > 0.0 else crossover
    return PlantGain(used * r_inv, used, float(crossover), modes.first_mode, modes.modal_decay, modes.decay, rho)
