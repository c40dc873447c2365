"""Test oracle: the PCC pose Jacobian and cable lengths written with vectorised numpy.

An independent formulation of what ``continuum_sim.kinematics_kernels`` computes: the
section end as the weighted sum over its segments (not the kernel's closed form), the
section's angular velocity from SO(3)'s left Jacobian, the cable pieces as ``|t + R(s + h)
- h|`` for all holes at once. Tests compare the compiled kernels with it within stated
tolerances; nothing in the package imports it.
"""

from __future__ import annotations

import numpy as np

from continuum_sim import kinematics as kin
from continuum_sim.geometry import ArmGeometry, SectionGeometry


def _dsinc_over_a(a: np.ndarray) -> np.ndarray:
    """(d/da sinc a)/a = (a cos a - sin a)/a³, finite at 0 (-1/3)."""
    small = np.abs(a) < 1e-2
    safe = np.where(small, 1.0, a)
    a2 = a * a
    return np.where(small, -1.0 / 3.0 + a2 / 30.0 - a2 * a2 / 840.0 + a2**3 / 45360.0,
                    (safe * np.cos(safe) - np.sin(safe)) / safe**3)


def _a_minus_sin_over_cube(a: np.ndarray) -> np.ndarray:
    """(a - sin a)/a³."""
    small = np.abs(a) < 1e-2
    safe = np.where(small, 1.0, a)
    a2 = a * a
    return np.where(small, 1.0 / 6.0 - a2 / 120.0 + a2 * a2 / 5040.0, (safe - np.sin(safe)) / safe**3)


def left_jacobian_so3(w: np.ndarray) -> np.ndarray:
    """J_l(w): d exp(w) exp(w)ᵀ = [J_l(w) dw]×, i.e. spatial angular velocity per dw."""
    theta = np.linalg.norm(w, axis=-1)
    K = kin.skew(w)
    return (np.eye(3) + kin._one_minus_cos_over_sq(theta)[..., None, None] * K
            + _a_minus_sin_over_cube(theta)[..., None, None] * (K @ K))


def section_derivatives(section: SectionGeometry, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(dp, dw): (..., 2, 3) position derivatives and spatial angular velocities per unit (du, dv), section frame."""
    theta = np.hypot(u, v)
    n = section.n_segments
    beta = np.arange(n + 1) / n
    c = np.full(n + 1, 2.0)
    c[0] = c[-1] = 1.0
    half = section.pitch / 2.0
    a = theta[..., None] * beta
    g = half * np.sum(c * beta * kin._sinc(a), axis=-1)  # x(θ)/θ
    h = half * np.sum(c * beta**3 * _dsinc_over_a(a), axis=-1)  # g'(θ)/θ
    m = -half * np.sum(c * beta**2 * kin._sinc(a), axis=-1)  # z'(θ)/θ
    dp = np.stack([np.stack([g + u * u * h, u * v * h, m * u], -1), np.stack([u * v * h, g + v * v * h, m * v], -1)], -2)
    Jl = left_jacobian_so3(np.stack([-v, u, np.zeros_like(u)], -1))
    return dp, np.stack([Jl[..., :, 1], -Jl[..., :, 0]], -2)  # d rotvec/du = e_y, /dv = -e_x


def jacobian_bending(geometry: ArmGeometry, w: np.ndarray, tool_length: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(T (..., 4, 4), J (..., 6, 2S)): tool pose and Jacobian in the arm base frame."""
    w = np.asarray(w, dtype=float)
    T = np.broadcast_to(np.eye(4), w.shape[:-1] + (4, 4)).copy()
    parts = []
    for k, section in enumerate(geometry.sections):
        R, p = kin.section_transform_bending(section, w[..., 2 * k], w[..., 2 * k + 1])
        dp, dw = section_derivatives(section, w[..., 2 * k], w[..., 2 * k + 1])
        Rk = T[..., :3, :3]
        parts.append((np.einsum("...ij,...cj->...ci", Rk, dp), np.einsum("...ij,...cj->...ci", Rk, dw)))
        T = T @ kin._homogeneous(R, p)
        parts[-1] += (T[..., :3, 3].copy(),)
    point = T[..., :3, 3] + tool_length * T[..., :3, 2]
    T[..., :3, 3] = point
    J = np.zeros(w.shape[:-1] + (6, 2 * geometry.n_sections))
    for k, (dp_w, dw_w, end) in enumerate(parts):
        for c in range(2):
            J[..., :3, 2 * k + c] = dp_w[..., c, :] + np.cross(dw_w[..., c, :], point - end)
            J[..., 3:, 2 * k + c] = dw_w[..., c, :]
    return T, J


def cable_lengths_bending(geometry: ArmGeometry, w: np.ndarray) -> np.ndarray:
    """(..., n_cables): n_m · |t + R(s + h) - h| summed over the sections each cable passes."""
    w = np.asarray(w, dtype=float)
    holes = geometry.cable_holes()  # (C, 3)
    cable_section = kin.cable_sections(geometry)
    total = np.zeros(w.shape[:-1] + (len(holes),))
    for m, section in enumerate(geometry.sections):
        rotvec = np.stack([-w[..., 2 * m + 1], w[..., 2 * m], np.zeros_like(w[..., 2 * m])], -1) / section.n_segments
        half = np.array([0.0, 0.0, section.pitch / 2.0])
        piece = half + np.einsum("...ij,cj->...ci", kin.exp_so3(rotvec), half + holes) - holes
        total += section.n_segments * np.linalg.norm(piece, axis=-1) * (cable_section >= m)
    return total
