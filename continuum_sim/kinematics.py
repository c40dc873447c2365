"""Discrete piecewise-constant-curvature kinematics (SPEC §2), exact for the MuJoCo model.

Each section is parameterised internally by its *bending coordinates*
``(u, v) = θ (cos φ, sin φ)``: the section's rotation is the rotation vector
``(-v, u, 0)``, smooth through the straight pose where φ is undefined. ``q`` in the
public API is ``(θ0, φ0, θ1, φ1, ...)``; ``w`` is ``(u0, v0, u1, v1, ...)``.

A segment of pitch p carries its upper disk by
``Trans(0,0,p/2) · Rz(φ)Ry(θ/n)Rz(-φ) · Trans(0,0,p/2)``, so the section's end lies at
``(p/2) Σ_j c_j R^j e_z`` with weights ``c = (1, 2, …, 2, 1)`` over ``j = 0..n`` and
``R^j = exp(j/n · (-v, u, 0))``. Writing that sum in terms of ``sinc`` keeps every
expression and its derivative finite at θ = 0. All functions broadcast over leading
batch dimensions of ``q``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .geometry import ArmGeometry, SectionGeometry

Array = NDArray[np.float64]

_SMALL = 1e-4  # below this |a|, Taylor series replace ratios of trig functions


# ------------------------------------------------------------------ scalar helpers
def _sinc(a: Array) -> Array:
    """sin(a)/a."""
    return np.sinc(a / np.pi)


def _dsinc_over_a(a: Array) -> Array:
    """(d/da sinc a)/a = (a cos a - sin a)/a³, finite at 0 (-1/3)."""
    a = np.asarray(a, dtype=float)
    small = np.abs(a) < 1e-2
    safe = np.where(small, 1.0, a)
    exact = (safe * np.cos(safe) - np.sin(safe)) / safe**3
    a2 = a * a
    series = -1.0 / 3.0 + a2 / 30.0 - a2 * a2 / 840.0 + a2**3 / 45360.0
    return np.where(small, series, exact)


def _one_minus_cos_over_sq(a: Array) -> Array:
    """(1 - cos a)/a²."""
    a = np.asarray(a, dtype=float)
    small = np.abs(a) < 1e-2
    safe = np.where(small, 1.0, a)
    a2 = a * a
    return np.where(small, 0.5 - a2 / 24.0 + a2 * a2 / 720.0, (1.0 - np.cos(safe)) / safe**2)


def _a_minus_sin_over_cube(a: Array) -> Array:
    """(a - sin a)/a³."""
    a = np.asarray(a, dtype=float)
    small = np.abs(a) < 1e-2
    safe = np.where(small, 1.0, a)
    a2 = a * a
    return np.where(small, 1.0 / 6.0 - a2 / 120.0 + a2 * a2 / 5040.0, (safe - np.sin(safe)) / safe**3)


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


def left_jacobian_so3(w: Array) -> Array:
    """J_l(w): d exp(w) exp(w)ᵀ = [J_l(w) dw]×, i.e. spatial angular velocity per dw."""
    w = np.asarray(w, dtype=float)
    theta = np.linalg.norm(w, axis=-1)
    K = skew(w)
    return (
        np.eye(3)
        + _one_minus_cos_over_sq(theta)[..., None, None] * K
        + _a_minus_sin_over_cube(theta)[..., None, None] * (K @ K)
    )


# ------------------------------------------------------------ coordinate changes
def _as_q(geometry: ArmGeometry, q: ArrayLike) -> Array:
    q = np.asarray(q, dtype=float)
    n = 2 * geometry.n_sections
    if q.shape[-1:] != (n,):
        raise ValueError(f"q must have {n} entries (θ, φ per section); got shape {q.shape}")
    return q


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


def section_transform_bending(section: SectionGeometry, u: ArrayLike, v: ArrayLike, *, derivatives: bool = False):
    """Section end pose in its base frame from bending coordinates.

    Returns ``(R, p)`` with shapes (..., 3, 3), (..., 3); with ``derivatives`` also
    ``(dp, dw)``: (..., 2, 3) position derivatives and (..., 2, 3) spatial angular
    velocities per unit (du, dv), both in the section's base frame.
    """
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    theta = np.hypot(u, v)
    beta, c = _section_weights(section.n_segments)
    half = section.pitch / 2.0
    a = theta[..., None] * beta  # (..., n+1)
    g = half * np.sum(c * beta * _sinc(a), axis=-1)  # x(θ)/θ
    z = half * np.sum(c * np.cos(a), axis=-1)
    rotvec = np.stack([-v, u, np.zeros_like(u)], -1)
    R = exp_so3(rotvec)
    p = np.stack([g * u, g * v, z], -1)
    if not derivatives:
        return R, p
    h = half * np.sum(c * beta**3 * _dsinc_over_a(a), axis=-1)  # g'(θ)/θ
    m = -half * np.sum(c * beta**2 * _sinc(a), axis=-1)  # z'(θ)/θ
    dp = np.stack(
        [
            np.stack([g + u * u * h, u * v * h, m * u], -1),
            np.stack([u * v * h, g + v * v * h, m * v], -1),
        ],
        -2,
    )
    Jl = left_jacobian_so3(rotvec)
    dw = np.stack([Jl[..., :, 1], -Jl[..., :, 0]], -2)  # d rotvec/du = e_y, /dv = -e_x
    return R, p, dp, dw


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
    that ``base`` maps into (the arm base frame by default).
    """
    w = np.asarray(w, dtype=float)
    S = geometry.n_sections
    T = np.broadcast_to(_base(base), w.shape[:-1] + (4, 4)).copy()
    parts = []
    for k, section in enumerate(geometry.sections):
        R, p, dp, dw = section_transform_bending(section, w[..., 2 * k], w[..., 2 * k + 1], derivatives=True)
        Rk = T[..., :3, :3]
        # Spatial derivatives of this section, expressed in the output frame.
        dp_w = np.einsum("...ij,...cj->...ci", Rk, dp)
        dw_w = np.einsum("...ij,...cj->...ci", Rk, dw)
        T = T @ _homogeneous(R, p)
        parts.append((dp_w, dw_w, T[..., :3, 3].copy()))
    point = T[..., :3, 3] + tool_length * T[..., :3, 2]
    T_out = T.copy()
    T_out[..., :3, 3] = point
    J = np.zeros(w.shape[:-1] + (6, 2 * S))
    for k, (dp_w, dw_w, end) in enumerate(parts):
        lever = point - end
        for c in range(2):
            J[..., :3, 2 * k + c] = dp_w[..., c, :] + np.cross(dw_w[..., c, :], lever)
            J[..., 3:, 2 * k + c] = dw_w[..., c, :]
    return T_out, J


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


def segment_cable_lengths_bending(geometry: ArmGeometry, w: ArrayLike) -> Array:
    """(..., S, n_cables) |l| of one segment of section m for every cable hole (paper eq. 5-7)."""
    w = np.asarray(w, dtype=float)
    holes = geometry.cable_holes()  # (C, 3)
    out = []
    for m, section in enumerate(geometry.sections):
        n = section.n_segments
        rotvec = np.stack([-w[..., 2 * m + 1], w[..., 2 * m], np.zeros_like(w[..., 2 * m])], -1) / n
        R = exp_so3(rotvec)  # (..., 3, 3)
        half = np.array([0.0, 0.0, section.pitch / 2.0])
        # l = t + R (s + h) - h, for all holes at once.
        l = half + np.einsum("...ij,cj->...ci", R, half + holes) - holes
        out.append(np.linalg.norm(l, axis=-1))
    return np.stack(out, axis=-2)


def cable_lengths_bending(geometry: ArmGeometry, w: ArrayLike) -> Array:
    """(..., n_cables) cable lengths from bending coordinates."""
    seg = segment_cable_lengths_bending(geometry, w)
    counts = np.array([s.n_segments for s in geometry.sections], dtype=float)
    passes = np.arange(geometry.n_sections)[:, None] <= cable_sections(geometry)[None, :]  # (S, C)
    return np.sum(seg * (counts[:, None] * passes), axis=-2)


def cable_lengths(geometry: ArmGeometry, q: ArrayLike) -> Array:
    """(..., 9) cable lengths in metres, section-major base→tip (section 0 cables 0,1,2, …)."""
    return cable_lengths_bending(geometry, to_bending(_as_q(geometry, q)))


def cable_length_changes(geometry: ArmGeometry, q: ArrayLike) -> Array:
    """Δl = length − straight length; negative where the motor has reeled cable in."""
    return cable_lengths(geometry, q) - straight_cable_lengths(geometry)


def motor_angles(geometry: ArmGeometry, q: ArrayLike) -> Array:
    """Motor angles (rad) = Δl / spool radius."""
    return cable_length_changes(geometry, q) / geometry.spool_radius


# ------------------------------------------------------- fast single-configuration
def _sinc_scalar(x: float) -> float:
    if abs(x) < 1e-4:
        x2 = x * x
        return 1.0 - x2 / 6.0 + x2 * x2 / 120.0
    return math.sin(x) / x


def _dsinc_over_x_scalar(x: float) -> float:
    """(x cos x - sin x)/x³, the series near 0 (same as ``_dsinc_over_a``)."""
    if abs(x) < 1e-2:
        x2 = x * x
        return -1.0 / 3.0 + x2 / 30.0 - x2 * x2 / 840.0 + x2 * x2 * x2 / 45360.0
    return (x * math.cos(x) - math.sin(x)) / (x * x * x)


def _one_minus_sinc_over_sq_scalar(x: float) -> float:
    """(1 - sin x / x)/x² = (x - sin x)/x³."""
    if abs(x) < 1e-2:
        x2 = x * x
        return 1.0 / 6.0 - x2 / 120.0 + x2 * x2 / 5040.0
    return (x - math.sin(x)) / (x * x * x)


class ArmKernel:
    """Tool pose and bending-coordinate Jacobian of ONE configuration, in plain Python floats.

    The IK solver evaluates one configuration at a time, where numpy's per-call overhead
    on 3×3 arrays costs more than the arithmetic; this scalar version is ~10× faster than
    ``jacobian_bending`` for a single ``w`` and agrees with it to rounding (tested). It
    uses the closed form of the section-end sum ``Σ c_j e^{ijθ/n} = cot(θ/2n)(sin θ +
    i(1 - cos θ))``, written with ``sinc`` so that it stays finite at θ = 0:
    ``x/θ = (L/2) cos a sinc²(θ/2)/sinc a``, ``z = L cos a sinc θ/sinc a``, ``a = θ/2n``.
    Frames: the arm base frame (no mount transform).
    """

    def __init__(self, geometry: ArmGeometry, tool_length: float = 0.0) -> None:
        self.n_sections = geometry.n_sections
        self.tool_length = float(tool_length)
        self._sections = [(float(s.length), float(s.n_segments)) for s in geometry.sections]

    def pose_jacobian(self, w, derivatives: bool = True):
        """``(R, p, J)``: R row-major 9 floats, p 3 floats, J row-major (6 × 2S) floats or None.

        J rows 0-2: linear velocity of the tool point, rows 3-5: angular velocity, per unit
        change of each bending coordinate (as ``jacobian_bending``).
        """
        S = self.n_sections
        # Accumulated rotation (row-major) and position.
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
        px = py = pz = 0.0
        cols = []  # per coordinate: (lin_x, lin_y, lin_z, ang_x, ang_y, ang_z, section index)
        ends = []
        sin, cos, sqrt = math.sin, math.cos, math.sqrt
        for k in range(S):
            L, n = self._sections[k]
            u = float(w[2 * k])
            v = float(w[2 * k + 1])
            t = sqrt(u * u + v * v)
            a = t / (2.0 * n)
            h = 0.5 * t
            ca = cos(a)
            if t < 1e-4:  # Taylor series of the sinc terms (a, t/2 < t as well)
                t2 = t * t
                a2 = a * a
                h2 = h * h
                sa = 1.0 - a2 / 6.0 + a2 * a2 / 120.0
                sh = 1.0 - h2 / 6.0 + h2 * h2 / 120.0
                st = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
            else:
                sin_t = sin(t)
                sa = sin(a) / a
                sh = sin(h) / h
                st = sin_t / t
            G = 0.5 * L * ca * sh * sh / sa
            Z = L * ca * st / sa
            A = st
            B = 0.5 * sh * sh  # (1 - cos t)/t²
            # Section rotation R = I + A K + B (r rᵀ - t² I), rotation vector r = (-v, u, 0).
            s00 = 1.0 - B * u * u
            s01 = -B * u * v
            s02 = A * u
            s11 = 1.0 - B * v * v
            s12 = A * v
            s22 = 1.0 - B * t * t
            # (s10 = s01, s20 = -s02, s21 = -s12)
            lx, ly, lz = G * u, G * v, Z
            if derivatives:
                n2 = 4.0 * n * n
                da = _dsinc_over_x_scalar(a)
                if t < 1e-2:
                    dh = _dsinc_over_x_scalar(h)
                    dt = _dsinc_over_x_scalar(t)
                    C = _one_minus_sinc_over_sq_scalar(t)
                else:
                    cos_t = cos(t)
                    t3 = t * t * t
                    dh = (h * cos(h) - sin(h)) / (h * h * h)
                    dt = (t * cos_t - sin_t) / t3
                    C = (t - sin_t) / t3
                Gp = 0.5 * L * (-sh * sh / n2 + ca * sh * dh / (2.0 * sa) - ca * sh * sh * da / (n2 * sa * sa))
                Zp = L * (-st / n2 + ca * dt / sa - ca * st * da / (n2 * sa * sa))
                # d p / du, d p / dv in the section base frame.
                du = (G + u * u * Gp, u * v * Gp, u * Zp)
                dv = (u * v * Gp, G + v * v * Gp, v * Zp)
                # Angular velocity per du (= Jl[:, 1]) and per dv (= -Jl[:, 0]).
                wu = (-C * u * v, 1.0 - C * v * v, -B * v)
                wv = (-(1.0 - C * u * u), C * u * v, B * u)
                for d, om in ((du, wu), (dv, wv)):
                    cols.append(
                        (
                            r00 * d[0] + r01 * d[1] + r02 * d[2],
                            r10 * d[0] + r11 * d[1] + r12 * d[2],
                            r20 * d[0] + r21 * d[1] + r22 * d[2],
                            r00 * om[0] + r01 * om[1] + r02 * om[2],
                            r10 * om[0] + r11 * om[1] + r12 * om[2],
                            r20 * om[0] + r21 * om[1] + r22 * om[2],
                        )
                    )
            # Advance the chain: p += R_acc · l ; R_acc = R_acc · R_sec.
            px, py, pz = (
                px + r00 * lx + r01 * ly + r02 * lz,
                py + r10 * lx + r11 * ly + r12 * lz,
                pz + r20 * lx + r21 * ly + r22 * lz,
            )
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = (
                r00 * s00 + r01 * s01 - r02 * s02,
                r00 * s01 + r01 * s11 - r02 * s12,
                r00 * s02 + r01 * s12 + r02 * s22,
                r10 * s00 + r11 * s01 - r12 * s02,
                r10 * s01 + r11 * s11 - r12 * s12,
                r10 * s02 + r11 * s12 + r12 * s22,
                r20 * s00 + r21 * s01 - r22 * s02,
                r20 * s01 + r21 * s11 - r22 * s12,
                r20 * s02 + r21 * s12 + r22 * s22,
            )
            ends.append((px, py, pz))
        tl = self.tool_length
        Px, Py, Pz = px + tl * r02, py + tl * r12, pz + tl * r22
        R = [r00, r01, r02, r10, r11, r12, r20, r21, r22]
        if not derivatives:
            return R, [Px, Py, Pz], None
        m = 2 * S
        J = [0.0] * (6 * m)
        for c, (vx, vy, vz, ox, oy, oz) in enumerate(cols):
            ex, ey, ez = ends[c // 2]
            ax, ay, az = Px - ex, Py - ey, Pz - ez
            J[c] = vx + oy * az - oz * ay
            J[m + c] = vy + oz * ax - ox * az
            J[2 * m + c] = vz + ox * ay - oy * ax
            J[3 * m + c] = ox
            J[4 * m + c] = oy
            J[5 * m + c] = oz
        return R, [Px, Py, Pz], J


class CableKernel:
    """Cable lengths of ONE configuration with little per-call overhead (control loops).

    Same closed-loop vectors as ``cable_lengths_bending`` (tested equal). Every (section,
    cable passing it) pair is one row: its segment vector is ``C_m @ (hx, hy, 1)``, where
    the 3×3 ``C_m`` holds section m's Rodrigues terms (``R s − h + half·z`` with
    ``s = h + half·z``); the per-section scalars are computed in plain Python and the 18
    rows in three numpy calls.
    """

    def __init__(self, geometry: ArmGeometry) -> None:
        holes = geometry.cable_holes()
        cable_section = cable_sections(geometry)
        pairs = [(m, c) for m in range(geometry.n_sections) for c in range(len(holes)) if cable_section[c] >= m]
        self._pair_section = np.array([m for m, _ in pairs], dtype=int)
        self._pair_holes = np.array([[holes[c][0], holes[c][1], 1.0] for _, c in pairs])
        self._sections = [(float(s.n_segments), float(s.pitch / 2.0)) for s in geometry.sections]
        # Sums n_m · |l_mc| over the sections each cable passes.
        self._gather = np.zeros((len(holes), len(pairs)))
        for p, (m, c) in enumerate(pairs):
            self._gather[c, p] = geometry.sections[m].n_segments

    def lengths(self, w: ArrayLike) -> Array:
        """(n_cables,) cable lengths at bending coordinates ``w``."""
        coefficients = []
        for m, (n, half) in enumerate(self._sections):
            rx, ry = -float(w[2 * m + 1]) / n, float(w[2 * m]) / n  # type: ignore[arg-type, index]  # rotation vector (rx, ry, 0)
            angle2 = rx * rx + ry * ry
            angle = math.sqrt(angle2)
            A = _sinc_scalar(angle)
            if angle < 1e-2:
                B = 0.5 - angle2 / 24.0 + angle2 * angle2 / 720.0
            else:
                B = (1.0 - math.cos(angle)) / angle2
            bxy = B * rx * ry
            coefficients.append(
                [
                    [-B * ry * ry, bxy, A * ry * half],
                    [bxy, -B * rx * rx, -A * rx * half],
                    [-A * ry, A * rx, (2.0 - B * angle2) * half],
                ]
            )
        rows = np.array(coefficients)[self._pair_section]
        segment = np.einsum("pij,pj->pi", rows, self._pair_holes)
        return self._gather @ np.sqrt(np.einsum("pi,pi->p", segment, segment))
