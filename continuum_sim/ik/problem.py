"""The IK problem in solver variables: bending coordinates, their bounds, and the weighted residual.

Objective (paper eq. 8-11): ``½‖r‖²`` with ``r = [k1 (P_tip - P*); k2 e]``, where ``e`` is
``log(R_tip R*ᵀ)^∨`` in ``full`` orientation mode (same norm as the paper's
``log(R_tipᵀ R*)``) and the tool-axis direction error in ``axis`` mode (2 components:
the roll about the tool axis is free, 5 constraints). Variables are the bending
coordinates ``w = θ(cos φ, sin φ)`` per section (smooth at the θ = 0 phase singularity)
with the disk bound ``|w_k| ≤ θmax_k``; in ``planar`` phase mode they are the signed
bending angles ``s_k`` with every φ fixed to the plane (φ ∈ {ψ, ψ+π}).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from .. import kinematics as kin
from ..geometry import ArmGeometry
from .options import Array, IKOptions, Orientation, Phase, check_mode


def wrap_angle(a: float) -> float:
    """Angle to (-π, π]."""
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi)) if not -math.pi < a <= math.pi else a


class Evaluation(NamedTuple):
    """The weighted residual at solver variables x (``IKSolver.evaluate``)."""

    residual: list[float]
    jacobian: Any  # (n_res, n_vars) array; None when derivatives were not asked for
    position_error: float  # m
    orientation_error: float  # rad
    rotation: list[float]  # tool rotation, row-major 3×3
    position: list[float]  # tool position


class IKProblem:
    """One arm, one tool, one mode, in the arm base frame: variables, bounds and residual.

    ``IKSolver`` (solver.py) minimises this residual; the split keeps the cost apart from
    the strategy that minimises it.
    """

    def __init__(
        self,
        geometry: ArmGeometry,
        orientation: Orientation = "full",
        phase: Phase = "free",
        tool_length: float = 0.0,
        plane_angle: float = 0.0,
        options: IKOptions | None = None,
    ) -> None:
        check_mode(orientation, phase)
        self.geometry = geometry
        self.orientation = orientation
        self.phase = phase
        self.tool_length = float(tool_length)
        self.plane_angle = float(plane_angle)
        self.options = options or IKOptions()
        from ..kinematics_kernels import ArmPose, sinc  # numba: loaded when a solver is built, not with the config

        self.kernel = ArmPose(geometry, tool_length)
        self._sinc = sinc
        self.S = geometry.n_sections
        self.bounds = [float(b) for b in geometry.max_bend]
        self.n_vars = self.S if phase == "planar" else 2 * self.S
        self._cpsi, self._spsi = math.cos(self.plane_angle), math.sin(self.plane_angle)
        self.reach = geometry.length + self.tool_length
        self._diag = (np.arange(self.n_vars), np.arange(self.n_vars))  # the normal matrix's diagonal, for damping
        # The last configuration's FK and Jacobian (they do not depend on the target): a solve
        # warm-started from the previous solution reuses them. Not thread-safe; one per thread.
        self._fk_cache: tuple | None = None


    # ---------------------------------------------------------------- variables
    def to_w(self, x) -> list[float]:
        if self.phase == "free":
            return [float(v) for v in x]
        c, s = self._cpsi, self._spsi
        w = []
        for sk in x:
            w.append(float(sk) * c)
            w.append(float(sk) * s)
        return w

    def x_from_q(self, q: ArrayLike) -> Array:
        """Solver variables from (θ, φ) pairs (planar: the bend projected onto the plane)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            v = q.tolist()
            if self.phase == "free":
                out = []
                for k in range(self.S):
                    out += [v[2 * k] * math.cos(v[2 * k + 1]), v[2 * k] * math.sin(v[2 * k + 1])]
                return np.array(out)
            return np.array([v[2 * k] * math.cos(v[2 * k + 1] - self.plane_angle) for k in range(self.S)])
        if self.phase == "free":
            return kin.to_bending(q)
        return q[..., 0::2] * np.cos(q[..., 1::2] - self.plane_angle)

    def q_from_x(self, x) -> Array:
        """(θ, φ) pairs with θ >= 0; planar: φ exactly ψ or ψ + π."""
        if self.phase == "free":
            v = [float(a) for a in x]
            out = []
            for k in range(self.S):
                u, w = v[2 * k], v[2 * k + 1]
                out += [math.hypot(u, w), math.atan2(w, u)]
            return np.array(out)
        x = np.asarray(x, dtype=float)
        q = np.empty(2 * self.S)
        q[0::2] = np.abs(x)
        q[1::2] = np.where(x >= 0.0, wrap_angle(self.plane_angle), wrap_angle(self.plane_angle + math.pi))
        return q

    def project(self, x: list[float]) -> list[float]:
        """Onto the bending bounds: the disk |w_k| ≤ θmax_k (free) or |s_k| ≤ θmax_k (planar)."""
        if self.phase == "planar":
            return [min(max(v, -b), b) for v, b in zip(x, self.bounds)]
        out = list(x)
        for k, b in enumerate(self.bounds):
            u, v = out[2 * k], out[2 * k + 1]
            t = math.hypot(u, v)
            if t > b:
                f = b / t
                out[2 * k], out[2 * k + 1] = u * f, v * f
        return out

    # ---------------------------------------------------------------- residual
    def _prepare(self, target: Array) -> tuple:
        P = target[:3, 3]
        R = target[:3, :3]
        return (float(P[0]), float(P[1]), float(P[2]), [float(v) for v in R.ravel()])

    def evaluate(self, x, tgt, derivatives: bool = True) -> Evaluation:
        """The residual, its Jacobian and the errors at solver variables ``x``."""
        k1, k2 = self.options.position_weight, self.options.orientation_weight
        w = self.to_w(x)
        cached = self._fk_cache
        if cached is not None and cached[0] == w:
            R, p, Jw = cached[1]
        else:
            R, p, Jw = self.kernel.pose_jacobian(w, derivatives)
            if derivatives:
                self._fk_cache = (w, (R, p, Jw))
        Px, Py, Pz, Rt = tgt
        dx, dy, dz = p[0] - Px, p[1] - Py, p[2] - Pz
        ep = math.sqrt(dx * dx + dy * dy + dz * dz)
        R0, R1, R2, R3, R4, R5, R6, R7, R8 = R
        T0, T1, T2, T3, T4, T5, T6, T7, T8 = Rt
        if self.orientation == "full":
            # F = R Rtᵀ, e = log(F)^∨ (spatial): the rotation from the target to the tip.
            F01 = R0 * T3 + R1 * T4 + R2 * T5
            F02 = R0 * T6 + R1 * T7 + R2 * T8
            F10 = R3 * T0 + R4 * T1 + R5 * T2
            F12 = R3 * T6 + R4 * T7 + R5 * T8
            F20 = R6 * T0 + R7 * T1 + R8 * T2
            F21 = R6 * T3 + R7 * T4 + R8 * T5
            trace = R0 * T0 + R1 * T1 + R2 * T2 + R3 * T3 + R4 * T4 + R5 * T5 + R6 * T6 + R7 * T7 + R8 * T8
            vx, vy, vz = F21 - F12, F02 - F20, F10 - F01
            cos_a = 0.5 * (trace - 1.0)
            sin_a = 0.5 * math.sqrt(vx * vx + vy * vy + vz * vz)
            angle = math.atan2(sin_a, cos_a)
            if angle > math.pi - 1e-3:
                F = np.array(R).reshape(3, 3) @ np.array(Rt).reshape(3, 3).T
                ex, ey, ez = (float(c) for c in kin.log_so3(F))
            else:
                f = 0.5 / self._sinc(angle)
                ex, ey, ez = vx * f, vy * f, vz * f
            eo = angle
            r = [k1 * dx, k1 * dy, k1 * dz, k2 * ex, k2 * ey, k2 * ez]
            if not derivatives:
                return Evaluation(r, None, ep, eo, R, p)
            m = 2 * self.S
            rows = [k1 * v for v in Jw[: 3 * m]]
            if 1e-8 < angle < 3.0:
                # d log(exp(ω) F) = Jl⁻¹(e) ω, Jl⁻¹ = I - E/2 + c E², E² = e eᵀ - |e|² I.
                # (Below 1e-8 rad Jl⁻¹ = I to within 1e-8.)
                if angle < 1e-3:
                    c = 1.0 / 12.0 + angle * angle / 720.0
                else:
                    c = 1.0 / angle**2 - (1.0 + math.cos(angle)) / (2.0 * angle * math.sin(angle))
                d = k2 * (1.0 - c * angle * angle)
                c *= k2
                h = 0.5 * k2
                m00, m01, m02 = d + c * ex * ex, h * ez + c * ex * ey, -h * ey + c * ex * ez
                m10, m11, m12 = -h * ez + c * ey * ex, d + c * ey * ey, h * ex + c * ey * ez
                m20, m21, m22 = h * ey + c * ez * ex, -h * ex + c * ez * ey, d + c * ez * ez
                ox, oy, oz = Jw[3 * m : 4 * m], Jw[4 * m : 5 * m], Jw[5 * m :]
                rows += [m00 * a + m01 * b + m02 * e for a, b, e in zip(ox, oy, oz)]
                rows += [m10 * a + m11 * b + m12 * e for a, b, e in zip(ox, oy, oz)]
                rows += [m20 * a + m21 * b + m22 * e for a, b, e in zip(ox, oy, oz)]
            else:
                rows += [k2 * v for v in Jw[3 * m :]]
            J = np.array(rows).reshape(6, m)
        else:
            ax, ay, az = R2, R5, R8
            c1 = ax * T0 + ay * T3 + az * T6  # a · x*
            c2 = ax * T1 + ay * T4 + az * T7  # a · y*
            c3 = ax * T2 + ay * T5 + az * T8  # a · z*
            sin_a = math.sqrt(c1 * c1 + c2 * c2)
            angle = math.atan2(sin_a, c3)
            # r = k2 (angle / sin angle) (c1, c2): the log map of S² at z*, zero only at a = z*.
            gain = k2 if angle < 1e-6 else k2 * angle / max(sin_a, 1e-12)
            eo = angle
            r = [k1 * dx, k1 * dy, k1 * dz, gain * c1, gain * c2]
            if not derivatives:
                return Evaluation(r, None, ep, eo, R, p)
            m = 2 * self.S
            rows = [k1 * v for v in Jw[: 3 * m]]
            # d(a·v) = ω · (a × v) for v = x*, y*, z*.
            n1 = (ay * T6 - az * T3, az * T0 - ax * T6, ax * T3 - ay * T0)
            n2 = (ay * T7 - az * T4, az * T1 - ax * T7, ax * T4 - ay * T1)
            ox, oy, oz = Jw[3 * m : 4 * m], Jw[4 * m : 5 * m], Jw[5 * m :]
            D1 = [n1[0] * a + n1[1] * b + n1[2] * e for a, b, e in zip(ox, oy, oz)]
            D2 = [n2[0] * a + n2[1] * b + n2[2] * e for a, b, e in zip(ox, oy, oz)]
            if angle < 1e-6:
                rows += [k2 * v for v in D1] + [k2 * v for v in D2]
            else:
                # gain' = k2 d(angle/s): s = sin angle = |(c1, c2)|, angle = atan2(s, c3).
                n3 = (ay * T8 - az * T5, az * T2 - ax * T8, ax * T5 - ay * T2)
                D3 = [n3[0] * a + n3[1] * b + n3[2] * e for a, b, e in zip(ox, oy, oz)]
                s = max(sin_a, 1e-12)
                den = s * s + c3 * c3
                r1, r2 = [], []
                for d1, d2, d3 in zip(D1, D2, D3):
                    ds = (c1 * d1 + c2 * d2) / s
                    dangle = (c3 * ds - s * d3) / den
                    dgain = k2 * (dangle * s - angle * ds) / (s * s)
                    r1.append(gain * d1 + c1 * dgain)
                    r2.append(gain * d2 + c2 * dgain)
                rows += r1 + r2
            J = np.array(rows).reshape(5, m)
        if self.phase == "planar":
            J = J[:, 0::2] * self._cpsi + J[:, 1::2] * self._spsi
        return Evaluation(r, J, ep, eo, R, p)

    # ---------------------------------------------------------------- success
    def _ok(self, ep: float, eo: float) -> bool:
        return ep <= self.options.position_tolerance and eo <= self.options.orientation_tolerance

    def _weighted(self, ep: float, eo: float) -> float:
        return (self.options.position_weight * ep) ** 2 + (self.options.orientation_weight * eo) ** 2
