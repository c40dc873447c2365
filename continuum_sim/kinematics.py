"""Discrete piecewise-constant-curvature kinematics (SPEC §2), exact for the MuJoCo model.

Each section is parameterised internally by its *bending coordinates*
``(u, v) = θ (cos φ, sin φ)``: the section's rotation is the rotation vector
``(-v, u, 0)``, smooth through the straight pose where φ is undefined. ``q`` in the
public API is ``(θ0, φ0, θ1, φ1, ...)``; ``w`` is ``(u0, v0, u1, v1, ...)``.

A segment of pitch p carries its upper disk by
``Trans(0,0,p/2) · Rz(φ)Ry(θ/n)Rz(-φ) · Trans(0,0,p/2)``, so the section's end lies at
``(p/2) Σ_j c_j R^j e_z`` with weights ``c = (1, 2, …, 2, 1)`` over ``j = 0..n`` and
``R^j = exp(j/n · (-v, u, 0))``. Writing that sum in terms of ``sinc`` keeps every
expression finite at θ = 0. All functions broadcast over leading batch dimensions of
``q``. The pose Jacobian and the cable lengths are computed, one configuration at a time,
by the compiled kernels of ``kinematics_kernels`` (the control tick's own), which this
module loads on first use so that importing it stays light.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .geometry import ArmGeometry, SectionGeometry

Array = NDArray[np.float64]

_SMALL = 1e-4  # below this |a|, Taylor series replace ratios of trig functions


# ------------------------------------------------------------------ scalar helpers
def _sinc(a: Array) -> Array:
    """sin(a)/a."""
    return np.sinc(a / np.pi)


def _one_minus_cos_over_sq(a: Array) -> Array:
    """(1 - cos a)/a²."""
    a = np.asarray(a, dtype=float)
    small = np.abs(a) < 1e-2
    safe = np.where(small, 1.0, a)
    a2 = a * a
    return np.where(small, 0.5 - a2 / 24.0 + a2 * a2 / 720.0, (1.0 - np.cos(safe)) / safe**2)


def skew(w: Array) -> Array:
    """(..., 3) -> (..., 3, 3) cross-product matrices."""
    w = np.asarray(w, dtype=float)
    z = np.zeros(w.shape[:-1])
    return np.stack(
        [
            np.stack([z, -w[..., 2], w[..., 1]], -1),
            np.stack([w[..., 2], z, -w[..., 0]], -1),
            np.stack([-w[..., 1], w[..., 0], z], -1),
        ],
        -2,
    )


def exp_so3(w: Array) -> Array:
    """Rodrigues: rotation vectors (..., 3) -> rotation matrices (..., 3, 3)."""
    w = np.asarray(w, dtype=float)
    theta = np.linalg.norm(w, axis=-1)
    K = skew(w)
    A = _sinc(theta)[..., None, None]
    B = _one_minus_cos_over_sq(theta)[..., None, None]
    return np.eye(3) + A * K + B * (K @ K)


def log_so3(R: Array) -> Array:
    """Rotation matrices (..., 3, 3) -> rotation vectors (..., 3), robust near 0 and π."""
    R = np.asarray(R, dtype=float)
    cos = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arccos(cos)
    vee = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    out = vee / (2.0 * _sinc(theta))[..., None]
    near_pi = theta > np.pi - 1e-2
    if np.any(near_pi):
        # vee/sin loses precision near π; the quaternion route does not.
        from scipy.spatial.transform import Rotation

        out[near_pi] = Rotation.from_matrix(R[near_pi]).as_rotvec()
    return out


# ------------------------------------------------------------ coordinate changes
def _as_q(geometry: ArmGeometry, q: ArrayLike) -> Array:
    q = np.asarray(q, dtype=float)
    n = 2 * geometry.n_sections
    if q.shape[-1:] != (n,):
        raise ValueError(f"q must have {n} entries (θ, φ per section); got shape {q.shape}")
    return q


def _as_w(geometry: ArmGeometry, w: ArrayLike) -> Array:
    """Bending coordinates as a C-contiguous float array, checked for 2S entries."""
    w = np.ascontiguousarray(w, dtype=np.float64)
    n = 2 * geometry.n_sections
    if w.shape[-1:] != (n,):
        raise ValueError(f"w must have {n} entries (u, v per section); got shape {w.shape}")
    return w


def to_bending(q: ArrayLike) -> Array:
    """(θ, φ) pairs -> bending coordinates (u, v) pairs."""
    q = np.asarray(q, dtype=float)
    theta, phi = q[..., 0::2], q[..., 1::2]
    w = np.empty_like(q)
    w[..., 0::2] = theta * np.cos(phi)
    w[..., 1::2] = theta * np.sin(phi)
    return w


def from_bending(w: ArrayLike) -> Array:
    """(u, v) pairs -> (θ, φ) pairs with θ >= 0 and φ in (-π, π]; φ = 0 where θ = 0."""
    w = np.asarray(w, dtype=float)
    u, v = w[..., 0::2], w[..., 1::2]
    q = np.empty_like(w)
    q[..., 0::2] = np.hypot(u, v)
    q[..., 1::2] = np.arctan2(v, u)
    return q


def bending_chain_matrix(q: ArrayLike) -> Array:
    """d(u,v)/d(θ,φ), block diagonal (..., 2S, 2S): maps bending-Jacobians to q-Jacobians."""
    q = np.asarray(q, dtype=float)
    theta, phi = q[..., 0::2], q[..., 1::2]
    S = theta.shape[-1]
    M = np.zeros(q.shape[:-1] + (2 * S, 2 * S))
    for k in range(S):
        c, s, t = np.cos(phi[..., k]), np.sin(phi[..., k]), theta[..., k]
        M[..., 2 * k, 2 * k] = c
        M[..., 2 * k, 2 * k + 1] = -t * s
        M[..., 2 * k + 1, 2 * k] = s
        M[..., 2 * k + 1, 2 * k + 1] = t * c
    return M


# --------------------------------------------------------------- section level
def _section_weights(n: int) -> tuple[Array, Array]:
    """Fractions j/n and weights (1, 2, …, 2, 1) of the section-end sum."""
    beta = np.arange(n + 1) / n
    c = np.full(n + 1, 2.0)
    c[0] = c[-1] = 1.0
    return beta, c


def section_transform_bending(section: SectionGeometry, u: ArrayLike, v: ArrayLike) -> tuple[Array, Array]:
    """Section end pose ``(R, p)`` in its base frame from bending coordinates: (..., 3, 3), (..., 3)."""
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    theta = np.hypot(u, v)
    beta, c = _section_weights(section.n_segments)
    half = section.pitch / 2.0
    a = theta[..., None] * beta  # (..., n+1)
    g = half * np.sum(c * beta * _sinc(a), axis=-1)  # x(θ)/θ
    z = half * np.sum(c * np.cos(a), axis=-1)
    R = exp_so3(np.stack([-v, u, np.zeros_like(u)], -1))
    return R, np.stack([g * u, g * v, z], -1)


def continuous_section_transform_bending(section: SectionGeometry, u: ArrayLike, v: ArrayLike) -> tuple[Array, Array]:
    """The n → ∞ limit: a circular arc, x = L(1-cos θ)/θ, z = L sin θ/θ in its plane."""
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    theta = np.hypot(u, v)
    L = section.length
    g = L * _one_minus_cos_over_sq(theta)
    R = exp_so3(np.stack([-v, u, np.zeros_like(u)], -1))
    return R, np.stack([g * u, g * v, L * _sinc(theta)], -1)


def _homogeneous(R: Array, p: Array) -> Array:
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def _base(base: ArrayLike | None) -> Array:
    return np.eye(4) if base is None else np.asarray(base, dtype=float)


# ------------------------------------------------------------------- arm level
def forward_kinematics_bending(geometry: ArmGeometry, w: ArrayLike, base: ArrayLike | None = None, tool_length: float = 0.0) -> Array:
    """Tip pose (4, 4) (or tool-centre pose with ``tool_length``) from bending coordinates."""
    w = np.asarray(w, dtype=float)
    T = np.broadcast_to(_base(base), w.shape[:-1] + (4, 4)).copy()
    for k, section in enumerate(geometry.sections):
        R, p = section_transform_bending(section, w[..., 2 * k], w[..., 2 * k + 1])
        T = T @ _homogeneous(R, p)
    if tool_length:
        T[..., :3, 3] += tool_length * T[..., :3, 2]
    return T


def forward_kinematics(geometry: ArmGeometry, q: ArrayLike, base: ArrayLike | None = None) -> Array:
    """Arm tip (last disk centre) pose (4, 4) in the arm base frame (or ``base`` · that)."""
    return forward_kinematics_bending(geometry, to_bending(_as_q(geometry, q)), base)


def tool_centre_pose(geometry: ArmGeometry, q: ArrayLike, tool: str | float, base: ArrayLike | None = None) -> Array:
    """Tool-centre-point pose: the tip moved along its z by the tool length."""
    length = geometry.tools.length(tool) if isinstance(tool, str) else float(tool)
    return forward_kinematics_bending(geometry, to_bending(_as_q(geometry, q)), base, length)


def continuous_forward_kinematics(geometry: ArmGeometry, q: ArrayLike, base: ArrayLike | None = None) -> Array:
    """Tip pose of the continuous constant-curvature arcs (the n → ∞ limit)."""
    w = to_bending(_as_q(geometry, q))
    T = np.broadcast_to(_base(base), w.shape[:-1] + (4, 4)).copy()
    for k, section in enumerate(geometry.sections):
        T = T @ _homogeneous(*continuous_section_transform_bending(section, w[..., 2 * k], w[..., 2 * k + 1]))
    return T


def segment_transform(section: SectionGeometry, theta: ArrayLike, phi: ArrayLike) -> Array:
    """SPEC §2's T_seg = Trans(p/2) · Rz(φ)Ry(θ/n)Rz(-φ) · Trans(p/2) as (..., 4, 4)."""
    theta = np.asarray(theta, dtype=float)
    phi = np.asarray(phi, dtype=float)
    n = section.n_segments
    R = exp_so3(np.stack([-np.sin(phi), np.cos(phi), np.zeros_like(phi)], -1) * (theta / n)[..., None])
    half = np.array([0.0, 0.0, section.pitch / 2.0])
    return _homogeneous(R, half + R @ half)


def disk_frames(geometry: ArmGeometry, q: ArrayLike, base: ArrayLike | None = None) -> Array:
    """Pose of every disk centre, base plate first: (..., n_disks, 4, 4)."""
    q = _as_q(geometry, q)
    T = np.broadcast_to(_base(base), q.shape[:-1] + (4, 4)).copy()
    frames = [T]
    for k, section in enumerate(geometry.sections):
        step = segment_transform(section, q[..., 2 * k], q[..., 2 * k + 1])
        for _ in range(section.n_segments):
            T = T @ step
            frames.append(T)
    return np.stack(frames, axis=-3)


def section_end_frames(geometry: ArmGeometry, q: ArrayLike, base: ArrayLike | None = None) -> Array:
    """Base frame then the end frame of each section: (..., S+1, 4, 4)."""
    w = to_bending(_as_q(geometry, q))
    T = np.broadcast_to(_base(base), w.shape[:-1] + (4, 4)).copy()
    frames = [T]
    for k, section in enumerate(geometry.sections):
        T = T @ _homogeneous(*section_transform_bending(section, w[..., 2 * k], w[..., 2 * k + 1]))
        frames.append(T)
    return np.stack(frames, axis=-3)


def jacobian_bending(geometry: ArmGeometry, w: ArrayLike, base: ArrayLike | None = None, tool_length: float = 0.0) -> tuple[Array, Array]:
    """Pose and geometric Jacobian w.r.t. bending coordinates.

    Returns ``(T, J)``: T (..., 4, 4) the tip (or tool-centre) pose; J (..., 6, 2S) with rows
    0-2 the point's linear velocity and rows 3-5 the angular velocity, both in the frame
    that ``base`` maps into (the arm base frame by default). Each configuration is one call
    of the compiled ``kinematics_kernels.pose_jacobian`` (numba, loaded on first use).
    """
    from .kinematics_kernels import model_pose_jacobian, pose_model

    w = _as_w(geometry, w)
    model = pose_model(geometry, tool_length)
    flat = w.reshape(-1, w.shape[-1])
    poses = np.zeros((len(flat), 4, 4))
    jacobians = np.empty((len(flat), 6, w.shape[-1]))
    R, p = np.empty(9), np.empty(3)
    for i in range(len(flat)):
        model_pose_jacobian(model, flat[i], R, p, jacobians[i].reshape(-1), True)
        poses[i, :3, :3], poses[i, :3, 3], poses[i, 3, 3] = R.reshape(3, 3), p, 1.0
    T: Array = poses.reshape(w.shape[:-1] + (4, 4))
    J: Array = jacobians.reshape(w.shape[:-1] + jacobians.shape[-2:])
    if base is None:
        return T, J
    B = np.broadcast_to(_base(base), T.shape)
    return B @ T, np.concatenate([B[..., :3, :3] @ J[..., :3, :], B[..., :3, :3] @ J[..., 3:, :]], axis=-2)


def jacobian(geometry: ArmGeometry, q: ArrayLike, base: ArrayLike | None = None, tool_length: float = 0.0) -> Array:
    """Geometric Jacobian (..., 6, 2S) of the tip (or tool-centre) pose w.r.t. q = (θ, φ)."""
    q = _as_q(geometry, q)
    _, J = jacobian_bending(geometry, to_bending(q), base, tool_length)
    return J @ bending_chain_matrix(q)


# ---------------------------------------------------------------------- cables
def cable_sections(geometry: ArmGeometry) -> Array:
    """Section index of every cable (three per section, base to tip)."""
    return np.repeat(np.arange(geometry.n_sections), 3)


def straight_cable_lengths(geometry: ArmGeometry) -> Array:
    """(n_cables,) cable lengths of the straight arm: Σ of the lengths of the sections passed."""
    cumulative = np.cumsum([s.length for s in geometry.sections])
    return cumulative[cable_sections(geometry)]


def cable_lengths_bending(geometry: ArmGeometry, w: ArrayLike) -> Array:
    """(..., n_cables) cable lengths from bending coordinates (paper eq. 5-7).

    Each configuration is one call of the compiled ``kinematics_kernels.cable_lengths``
    (numba, loaded on first use), the control tick's own kernel.
    """
    from .kinematics_kernels import cable_model, model_cable_lengths

    w = _as_w(geometry, w)
    model = cable_model(geometry)
    flat = w.reshape(-1, w.shape[-1])
    out = np.empty((len(flat), 3 * geometry.n_sections))
    for i in range(len(flat)):
        model_cable_lengths(model, flat[i], out[i])
    return out.reshape(w.shape[:-1] + (out.shape[-1],))


def cable_lengths(geometry: ArmGeometry, q: ArrayLike) -> Array:
    """(..., 9) cable lengths in metres, section-major base→tip (section 0 cables 0,1,2, …)."""
    return cable_lengths_bending(geometry, to_bending(_as_q(geometry, q)))


def cable_length_changes(geometry: ArmGeometry, q: ArrayLike) -> Array:
    """Δl = length − straight length; negative where the motor has reeled cable in."""
    return cable_lengths(geometry, q) - straight_cable_lengths(geometry)


def motor_angles(geometry: ArmGeometry, q: ArrayLike) -> Array:
    """Motor angles (rad) = Δl / spool radius."""
    return cable_length_changes(geometry, q) / geometry.spool_radius
