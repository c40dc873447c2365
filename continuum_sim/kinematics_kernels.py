"""Compiled PCC kinematics of ONE configuration: tool pose, its Jacobian, cable lengths.

The only implementation of the arm's pose Jacobian and of the per-configuration cable
lengths. The control tick (``control.kernels``) calls the kernels from compiled code, the
IK solver (``ik``) and ``kinematics.jacobian`` through ``ArmPose`` / ``pose_jacobian``.
Tests compare them with an independent vectorised formulation (``tests/kinematics_oracle.py``)
and finite differences of ``kinematics.forward_kinematics_bending`` within stated tolerances.

The pose uses the closed form of the section-end sum ``Σ c_j e^{ijθ/n} = cot(θ/2n)(sin θ +
i(1 - cos θ))``, written with ``sinc`` so that it stays finite at θ = 0:
``x/θ = (L/2) cos a sinc²(θ/2)/sinc a``, ``z = L cos a sinc θ/sinc a``, ``a = θ/2n``.
Frames: the arm base frame (no mount transform). Geometry lives in typed records
(``pose_dtype``, ``cable_dtype``: numpy structured dtypes with named fields; Python passes
the (1,) record arrays of ``pose_model``/``cable_model`` to ``model_pose_jacobian``/``model_cable_lengths``).

Importing this module imports numba (compiled on first call, cached on disk); modules a
configuration loads import it when a solver or controller is built.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from .geometry import ArmGeometry

Array = NDArray[np.float64]
Record = Any  # one record of a structured array (pose_dtype / cable_dtype): numba reads its fields as attributes

# nopython, cached on disk, no fast-math (IEEE arithmetic as written), releases the GIL.
jit = njit(cache=True, fastmath=False, nogil=True)


def pose_dtype(n_sections: int) -> np.dtype:
    """Record of what one arm's tool pose depends on (fixed for a run)."""
    return np.dtype([
        ("lengths", np.float64, (n_sections,)),  # m, section lengths
        ("segments", np.float64, (n_sections,)),  # segments per section (as floats)
        ("tool_length", np.float64),  # m, tool-centre point along the tip's z
    ])


def cable_dtype(n_sections: int, n_pairs: int) -> np.dtype:
    """Record of the cable routing: one row per (section, cable passing it) pair."""
    return np.dtype([
        ("segments", np.float64, (n_sections,)),  # segments per section (as floats)
        ("halves", np.float64, (n_sections,)),  # m, half the segment pitch
        ("pair_section", np.int64, (n_pairs,)),  # section of each pair
        ("pair_cable", np.int64, (n_pairs,)),  # cable of each pair
        ("pair_holes", np.float64, (n_pairs, 2)),  # m, the cable's hole (x, y) in a disk frame
    ])


def pose_model(geometry: ArmGeometry, tool_length: float = 0.0) -> NDArray[np.void]:
    """The pose record of ``geometry`` with a tool of ``tool_length`` (m): a (1,) structured array."""
    model = np.zeros(1, dtype=pose_dtype(geometry.n_sections))
    model["lengths"][0] = [float(s.length) for s in geometry.sections]
    model["segments"][0] = [float(s.n_segments) for s in geometry.sections]
    model["tool_length"][0] = float(tool_length)
    return model


def cable_model(geometry: ArmGeometry) -> NDArray[np.void]:
    """The cable record of ``geometry`` (cables three per section, section-major, base to tip): a (1,) structured array."""
    holes = geometry.cable_holes()
    cable_section = np.repeat(np.arange(geometry.n_sections), 3)
    pairs = [(m, c) for m in range(geometry.n_sections) for c in range(len(holes)) if cable_section[c] >= m]
    model = np.zeros(1, dtype=cable_dtype(geometry.n_sections, len(pairs)))
    model["segments"][0] = [float(s.n_segments) for s in geometry.sections]
    model["halves"][0] = [float(s.pitch) / 2.0 for s in geometry.sections]
    model["pair_section"][0] = [m for m, _ in pairs]
    model["pair_cable"][0] = [c for _, c in pairs]
    model["pair_holes"][0] = [[holes[c][0], holes[c][1]] for _, c in pairs]
    return model


@jit
def sinc(x: float) -> float:
    """sin(x)/x, its Taylor series near 0."""
    if abs(x) < 1e-4:
        x2 = x * x
        return 1.0 - x2 / 6.0 + x2 * x2 / 120.0
    return math.sin(x) / x


@jit
def _dsinc_over_x(x: float) -> float:
    """(x cos x - sin x)/x³, finite at 0 (-1/3)."""
    if abs(x) < 1e-2:
        x2 = x * x
        return -1.0 / 3.0 + x2 / 30.0 - x2 * x2 / 840.0 + x2 * x2 * x2 / 45360.0
    return (x * math.cos(x) - math.sin(x)) / (x * x * x)


@jit
def _one_minus_sinc_over_sq(x: float) -> float:
    """(1 - sin x / x)/x² = (x - sin x)/x³."""
    if abs(x) < 1e-2:
        x2 = x * x
        return 1.0 / 6.0 - x2 / 120.0 + x2 * x2 / 5040.0
    return (x - math.sin(x)) / (x * x * x)


@jit
def pose_jacobian(pose: Record, w: Array, R: Array, p: Array, J: Array, derivatives: bool) -> None:  # noqa: PLR0915
    """Tool pose and bending-coordinate Jacobian at ``w`` (u0, v0, u1, v1, ...) of the arm ``pose`` (a ``pose_dtype`` record).

    Writes R (9,) the tool frame row-major, p (3,) the tool point, and with ``derivatives``
    J (6·2S,) row-major: rows 0-2 the tool point's linear velocity, rows 3-5 the angular
    velocity, per unit change of each bending coordinate, in the arm base frame.
    """
    S = pose.lengths.shape[0]
    m = 2 * S
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    px = py = pz = 0.0
    cols = np.empty((m, 6))  # per coordinate: linear and angular velocity of the section's own motion
    ends = np.empty((S, 3))
    for k in range(S):
        L = pose.lengths[k]
        n = pose.segments[k]
        u = w[2 * k]
        v = w[2 * k + 1]
        t = math.sqrt(u * u + v * v)
        a = t / (2.0 * n)
        h = 0.5 * t
        ca = math.cos(a)
        sin_t = 0.0
        if t < 1e-4:  # Taylor series of the sinc terms (a, t/2 < t as well)
            t2 = t * t
            a2 = a * a
            h2 = h * h
            sa = 1.0 - a2 / 6.0 + a2 * a2 / 120.0
            sh = 1.0 - h2 / 6.0 + h2 * h2 / 120.0
            st = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
        else:
            sin_t = math.sin(t)
            sa = math.sin(a) / a
            sh = math.sin(h) / h
            st = sin_t / t
        G = 0.5 * L * ca * sh * sh / sa
        Z = L * ca * st / sa
        A = st
        B = 0.5 * sh * sh  # (1 - cos t)/t²
        # Section rotation I + A K + B (r rᵀ - t² I), rotation vector r = (-v, u, 0); s10 = s01, s20 = -s02, s21 = -s12.
        s00 = 1.0 - B * u * u
        s01 = -B * u * v
        s02 = A * u
        s11 = 1.0 - B * v * v
        s12 = A * v
        s22 = 1.0 - B * t * t
        lx, ly, lz = G * u, G * v, Z
        if derivatives:
            n2 = 4.0 * n * n
            da = _dsinc_over_x(a)
            if t < 1e-2:
                dh = _dsinc_over_x(h)
                dt = _dsinc_over_x(t)
                C = _one_minus_sinc_over_sq(t)
            else:
                cos_t = math.cos(t)
                t3 = t * t * t
                dh = (h * math.cos(h) - math.sin(h)) / (h * h * h)
                dt = (t * cos_t - sin_t) / t3
                C = (t - sin_t) / t3
            Gp = 0.5 * L * (-sh * sh / n2 + ca * sh * dh / (2.0 * sa) - ca * sh * sh * da / (n2 * sa * sa))
            Zp = L * (-st / n2 + ca * dt / sa - ca * st * da / (n2 * sa * sa))
            for c in range(2):
                if c == 0:  # d p/du, and the angular velocity per du (= Jl[:, 1])
                    d0, d1, d2 = G + u * u * Gp, u * v * Gp, u * Zp
                    o0, o1, o2 = -C * u * v, 1.0 - C * v * v, -B * v
                else:  # d p/dv, per dv (= -Jl[:, 0])
                    d0, d1, d2 = u * v * Gp, G + v * v * Gp, v * Zp
                    o0, o1, o2 = -(1.0 - C * u * u), C * u * v, B * u
                col = 2 * k + c
                cols[col, 0] = r00 * d0 + r01 * d1 + r02 * d2
                cols[col, 1] = r10 * d0 + r11 * d1 + r12 * d2
                cols[col, 2] = r20 * d0 + r21 * d1 + r22 * d2
                cols[col, 3] = r00 * o0 + r01 * o1 + r02 * o2
                cols[col, 4] = r10 * o0 + r11 * o1 + r12 * o2
                cols[col, 5] = r20 * o0 + r21 * o1 + r22 * o2
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
        ends[k, 0], ends[k, 1], ends[k, 2] = px, py, pz
    tl = pose.tool_length
    Px, Py, Pz = px + tl * r02, py + tl * r12, pz + tl * r22
    R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7], R[8] = r00, r01, r02, r10, r11, r12, r20, r21, r22
    p[0], p[1], p[2] = Px, Py, Pz
    if not derivatives:
        return
    for c in range(m):  # the tool point moves with each section's end: v + ω × (P - end)
        vx, vy, vz, ox, oy, oz = cols[c, 0], cols[c, 1], cols[c, 2], cols[c, 3], cols[c, 4], cols[c, 5]
        ax, ay, az = Px - ends[c // 2, 0], Py - ends[c // 2, 1], Pz - ends[c // 2, 2]
        J[c] = vx + oy * az - oz * ay
        J[m + c] = vy + oz * ax - ox * az
        J[2 * m + c] = vz + ox * ay - oy * ax
        J[3 * m + c] = ox
        J[4 * m + c] = oy
        J[5 * m + c] = oz


@jit
def cable_lengths(cables: Record, w: Array, out: Array) -> None:
    """Cable lengths (m) at bending coordinates ``w`` into ``out`` (paper eq. 5-7); ``cables`` a ``cable_dtype`` record.

    Section m's segment carries a hole h to ``R (h + half·z) + half·z``; the cable's piece
    through it is ``|half·z + R(h + half·z) - h|``, written ``C_m (hx, hy, 1)`` with the 3×3
    ``C_m`` of section m's Rodrigues terms (rotation vector ``(-v, u, 0)/n``); a cable sums
    n_m pieces over the sections it passes.
    """
    S = cables.segments.shape[0]
    coef = np.empty((S, 3, 3))
    for m in range(S):
        n = cables.segments[m]
        half = cables.halves[m]
        rx, ry = -w[2 * m + 1] / n, w[2 * m] / n
        angle2 = rx * rx + ry * ry
        angle = math.sqrt(angle2)
        A = sinc(angle)
        if angle < 1e-2:
            B = 0.5 - angle2 / 24.0 + angle2 * angle2 / 720.0
        else:
            B = (1.0 - math.cos(angle)) / angle2
        bxy = B * rx * ry
        coef[m, 0, 0], coef[m, 0, 1], coef[m, 0, 2] = -B * ry * ry, bxy, A * ry * half
        coef[m, 1, 0], coef[m, 1, 1], coef[m, 1, 2] = bxy, -B * rx * rx, -A * rx * half
        coef[m, 2, 0], coef[m, 2, 1], coef[m, 2, 2] = -A * ry, A * rx, (2.0 - B * angle2) * half
    out[:] = 0.0
    for q in range(cables.pair_section.shape[0]):
        m = cables.pair_section[q]
        hx, hy = cables.pair_holes[q, 0], cables.pair_holes[q, 1]
        s0 = coef[m, 0, 0] * hx + coef[m, 0, 1] * hy + coef[m, 0, 2]
        s1 = coef[m, 1, 0] * hx + coef[m, 1, 1] * hy + coef[m, 1, 2]
        s2 = coef[m, 2, 0] * hx + coef[m, 2, 1] * hy + coef[m, 2, 2]
        out[cables.pair_cable[q]] += cables.segments[m] * math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)


@jit
def model_pose_jacobian(model: NDArray[np.void], w: Array, R: Array, p: Array, J: Array, derivatives: bool) -> None:
    """``pose_jacobian`` of the record in the (1,) array ``model`` (``pose_model``): the entry point from Python."""
    pose_jacobian(model[0], w, R, p, J, derivatives)


@jit
def model_cable_lengths(model: NDArray[np.void], w: Array, out: Array) -> None:
    """``cable_lengths`` of the record in the (1,) array ``model`` (``cable_model``): the entry point from Python."""
    cable_lengths(model[0], w, out)


class ArmPose:
    """``pose_jacobian`` for Python callers evaluating one configuration at a time (the IK solver)."""

    def __init__(self, geometry: ArmGeometry, tool_length: float = 0.0) -> None:
        self.model = pose_model(geometry, tool_length)
        self._R, self._p, self._J = np.empty(9), np.empty(3), np.empty(12 * geometry.n_sections)

    def pose_jacobian(self, w: ArrayLike, derivatives: bool = True) -> tuple[list[float], list[float], list[float] | None]:
        """``(R, p, J)``: R row-major 9 floats, p 3 floats, J row-major (6 × 2S) floats or None."""
        model_pose_jacobian(self.model, np.asarray(w, dtype=np.float64), self._R, self._p, self._J, derivatives)
        return self._R.tolist(), self._p.tolist(), self._J.tolist() if derivatives else None
