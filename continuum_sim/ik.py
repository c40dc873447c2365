"""Optimisation inverse kinematics (SPEC §3; paper eq. 8-12).

Objective (paper eq. 8-11): ``½‖r‖²`` with ``r = [k1 (P_tip - P*); k2 e]``, where ``e`` is
``log(R_tip R*ᵀ)^∨`` in ``full`` orientation mode (same norm as the paper's
``log(R_tipᵀ R*)``) and the tool-axis direction error in ``axis`` mode (2 components:
the roll about the tool axis is free, 5 constraints). Variables are the bending
coordinates ``w = θ(cos φ, sin φ)`` per section (smooth at the θ = 0 phase singularity)
with the disk bound ``|w_k| ≤ θmax_k``; in ``planar`` phase mode they are the signed
bending angles ``s_k`` with every φ fixed to the plane (φ ∈ {ψ, ψ+π}).

Solver: projected Levenberg-Marquardt with the analytic Jacobian (``kinematics_kernels.ArmPose``) and
damping ``λ = μ‖r‖²``, which turns into plain Gauss-Newton near a zero-residual solution
(quadratic convergence, hence errors ~1e-13 after a few steps). Cold starts try a fixed
table of seed configurations ordered by how close their tool pose is to the target
(deterministic); warm starts begin at ``q0``. Paths are solved point by point, warm
started, with a per-step box on (Δθ, Δφ) and bisection of the toolpath where a step
would exceed it, so the shape never jumps quadrant (the defect of the paper's Fig. 9).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import kinematics as kin
from .configio import require_int, require_positive, require_range
from .geometry import ArmGeometry

# LAPACK's Cholesky routines (a tenth of np.linalg.solve's call overhead on 6×6), loaded by
# the first solver: importing scipy costs ~0.3 s, which loading a configuration should not pay.
_dposv: Any = None
_dpotrf: Any = None
_dpotrs: Any = None


def _load_lapack() -> None:
    global _dposv, _dpotrf, _dpotrs
    if _dposv is None:
        from scipy.linalg.lapack import dposv, dpotrf, dpotrs

        _dposv, _dpotrf, _dpotrs = dposv, dpotrf, dpotrs

Array = NDArray[np.float64]
Orientation = Literal["full", "axis"]
Phase = Literal["free", "planar"]
ORIENTATIONS = ("full", "axis")
PHASES = ("free", "planar")


# ------------------------------------------------------------------------ options
@dataclass(frozen=True)
class IKOptions:
    """Numerical settings of the solver (the problem itself is in ``solve_ik``'s arguments)."""

    position_weight: float = 10.0  # k1 of paper eq. 8, 1/m: 0.1 m of position ~ 1 rad
    orientation_weight: float = 1.0  # k2 of paper eq. 8, 1/rad
    position_tolerance: float = 1e-9  # m: success means both errors are within tolerance
    orientation_tolerance: float = 1e-9  # rad
    max_iterations: int = 60  # Levenberg-Marquardt iterations per start
    n_starts: int = 12  # cold starts tried (best-first from the seed table)
    seed_table_size: int = 384  # configurations in the cold-start table
    seed: int = 0  # of the seed table: same seed, same table, same answers
    max_step_rad: float = 0.6  # per-iteration trust radius per section, in bending coordinates

    def __post_init__(self) -> None:
        require_positive("position_weight", self.position_weight)
        require_positive("orientation_weight", self.orientation_weight)
        require_range("position_tolerance", self.position_tolerance, 0.0, 0.1)
        require_range("orientation_tolerance", self.orientation_tolerance, 0.0, 0.5)
        require_int("max_iterations", self.max_iterations, 1, 10_000)
        require_int("n_starts", self.n_starts, 1, 1000)
        require_int("seed_table_size", self.seed_table_size, 1, 100_000)
        require_int("seed", self.seed, 0, 2**32 - 1)
        require_range("max_step_rad", self.max_step_rad, 0.0, 10.0)


@dataclass(frozen=True)
class StepLimits:
    """Per-step bounds between neighbouring solved path points (the box of paper §4.3).

    Δφ is not bounded where a section is bent less than ``phase_free_below_deg`` at either
    end of the step: there the phase is (nearly) undefined and a large Δφ is a small
    change of shape (in planar mode it is the sign change of θ through zero).
    """

    max_dtheta_deg: float = 3.0
    max_dphi_deg: float = 20.0
    phase_free_below_deg: float = 3.0
    max_subdivisions: int = 8  # bisections of one toolpath step before giving up

    def __post_init__(self) -> None:
        require_range("max_dtheta_deg", self.max_dtheta_deg, 0.0, 180.0)
        require_range("max_dphi_deg", self.max_dphi_deg, 0.0, 360.0)
        require_range("phase_free_below_deg", self.phase_free_below_deg, 0.0, 90.0, low_inclusive=True)
        require_int("max_subdivisions", self.max_subdivisions, 0, 20)

    @property
    def max_dtheta(self) -> float:
        return math.radians(self.max_dtheta_deg)

    @property
    def max_dphi(self) -> float:
        return math.radians(self.max_dphi_deg)

    @property
    def phase_free_below(self) -> float:
        return math.radians(self.phase_free_below_deg)


# ------------------------------------------------------------------------ results
@dataclass(frozen=True)
class IKResult:
    """One solved pose. ``pose`` is the achieved pose in the frame of the target."""

    q: Array  # (θ0, φ0, θ1, φ1, ...), θ >= 0, φ in (-π, π]
    w: Array  # bending coordinates
    pose: Array
    position_error: float  # m, |P - P*|
    orientation_error: float  # rad: rotation angle (full) or tool-axis angle (axis)
    success: bool
    iterations: int
    message: str = ""

    def to_dict(self) -> dict:
        return {
            "success": bool(self.success),
            "q_rad": self.q.tolist(),
            "q_deg": np.degrees(self.q).tolist(),
            "position_error_m": float(self.position_error),
            "orientation_error_rad": float(self.orientation_error),
            "iterations": int(self.iterations),
            "achieved_pose": self.pose.tolist(),
            "message": self.message,
        }


# ------------------------------------------------------------------ target checks
def validate_pose(target: ArrayLike, name: str = "target") -> Array:
    """A (4, 4) homogeneous transform with a proper rotation, else a one-line ValueError."""
    T = np.asarray(target, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f"{name}: must be a (4, 4) homogeneous transform (got shape {T.shape})")
    v = T.ravel().tolist()
    if not all(map(math.isfinite, v)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    if max(abs(v[12]), abs(v[13]), abs(v[14]), abs(v[15] - 1.0)) > 1e-9:
        raise ValueError(f"{name}: last row must be [0, 0, 0, 1] (got {v[12:]})")
    a, b, c, d, e, f, g, h, i = v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]
    ortho = max(
        abs(a * a + d * d + g * g - 1.0),
        abs(b * b + e * e + h * h - 1.0),
        abs(c * c + f * f + i * i - 1.0),
        abs(a * b + d * e + g * h),
        abs(a * c + d * f + g * i),
        abs(b * c + e * f + h * i),
    )
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    if ortho > 1e-6 or det < 0.0:
        raise ValueError(
            f"{name}: rotation part is not a rotation matrix (max |RᵀR - I| = {ortho:.3g}, det = {det:.6g}; "
            "allowed: orthonormal within 1e-6 and det = +1)"
        )
    return T


def _check_mode(orientation: str, phase: str) -> None:
    if orientation not in ORIENTATIONS:
        raise ValueError(f"orientation: must be one of {', '.join(ORIENTATIONS)} (got {orientation!r})")
    if phase not in PHASES:
        raise ValueError(f"phase: must be one of {', '.join(PHASES)} (got {phase!r})")


def tool_length_of(geometry: ArmGeometry, tool: str | float) -> float:
    """Tool offset along the tip z: a tool name ('grinder', 'gripper', 'none') or metres."""
    if isinstance(tool, str):
        return geometry.tools.length(tool)
    length = float(tool)
    if not math.isfinite(length) or not 0.0 <= length <= 1.0:
        raise ValueError(f"tool: tool length must satisfy 0 <= tool <= 1 m (got {tool!r})")
    return length


# --------------------------------------------------------------------- the solver
def _wrap(a: float) -> float:
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


class Iterate(NamedTuple):
    """Where a Levenberg-Marquardt run ended (``IKSolver._lm``)."""

    x: list[float]
    position_error: float
    orientation_error: float
    iterations: int
    rotation: list[float]
    position: list[float]


class ChordIterate(NamedTuple):
    """Where the warm-start chord iteration ended (``IKSolver._chord``)."""

    x: list[float]
    residual: list[float]
    jacobian: Any  # array, or None
    position_error: float
    orientation_error: float
    rotation: list[float]
    position: list[float]
    iterations: int
    converged: bool


class Solution(NamedTuple):
    """``IKSolver.solve``'s answer in solver variables (``solve_ik`` wraps it in an ``IKResult``)."""

    x: list[float]
    position_error: float
    orientation_error: float
    iterations: int
    success: bool
    message: str
    rotation: list[float]
    position: list[float]


class IKSolver:
    """IK for one arm, one tool, one mode, in the arm base frame; reusable across targets.

    ``solve_ik`` caches these per (geometry, mode, tool, options); build one directly to
    solve many targets without even the cache lookup.
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
        _check_mode(orientation, phase)
        _load_lapack()
        self.geometry = geometry
        self.orientation = orientation
        self.phase = phase
        self.tool_length = float(tool_length)
        self.plane_angle = float(plane_angle)
        self.options = options or IKOptions()
        from .kinematics_kernels import ArmPose, sinc  # numba: loaded when a solver is built, not with the config

        self.kernel = ArmPose(geometry, tool_length)
        self._sinc = sinc
        self.S = geometry.n_sections
        self.bounds = [float(b) for b in geometry.max_bend]
        self.n_vars = self.S if phase == "planar" else 2 * self.S
        self._cpsi, self._spsi = math.cos(self.plane_angle), math.sin(self.plane_angle)
        self.reach = geometry.length + self.tool_length
        self._seeds: tuple[Array, Array, Array] | None = None
        # The last configuration's FK and Jacobian (they do not depend on the target), and
        # the last solution as (q, x): a solve warm-started from the previous solution
        # reuses both instead of recomputing them. Not thread-safe; one solver per thread.
        self._fk_cache: tuple | None = None
        self._last: tuple[Array, list[float]] | None = None
        k1, k2 = self.options.position_weight, self.options.orientation_weight
        self._row_weights = np.array([[k1], [k1], [k1], [k2], [k2], [k2]])
        self._diag = (np.arange(self.n_vars), np.arange(self.n_vars))

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
        q[1::2] = np.where(x >= 0.0, _wrap(self.plane_angle), _wrap(self.plane_angle + math.pi))
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

    # ---------------------------------------------------------------- LM core
    TAU = 1e-10  # initial damping relative to the largest diagonal entry of JᵀJ

    def _lm(self, x0, tgt, max_iterations: int, max_step: float) -> Iterate:
        """Projected Levenberg-Marquardt from ``x0``.

        Damping starts tiny (a Gauss-Newton step) and adapts by the gain ratio (Nielsen's
        rule); the floor ``1e-12·tr(JᵀJ)`` keeps the step out of the null space in the
        redundant ``axis`` mode. Each section's step is capped at ``max_step``. Written
        for one small problem at a time: few numpy calls per iteration.
        """
        opts = self.options
        stop_p = 1e-2 * opts.position_tolerance  # quadratic convergence: one step past 1e-2·tol is ~1e-15
        stop_o = 1e-2 * opts.orientation_tolerance
        x = self.project([float(v) for v in x0])
        r, J, ep, eo, R, p = self.evaluate(x, tgt)
        cost = sum(v * v for v in r)
        n = self.n_vars
        S = self.S
        planar = self.phase == "planar"
        dposv = _dposv
        diag = self._diag
        lam = -1.0
        nu = 2.0
        scale = floor = 0.0
        its = 0
        while its < max_iterations and not (ep <= stop_p and eo <= stop_o):
            its += 1
            JT = J.T
            A = JT.dot(J)
            g = JT.dot(r)
            if lam < 0.0:
                scale = float(A.trace()) / n
                lam = self.TAU * scale
                floor = 1e-12 * scale + 1e-300
            damping = lam + floor
            A[diag] += damping
            _, sol, info = dposv(A, g)
            if info != 0:
                break
            delta = sol.tolist()  # the step is -sol
            # Trust region: no section's bending coordinates move more than max_step.
            if planar:
                biggest = max(abs(d) for d in delta)
            else:
                biggest = math.sqrt(max(delta[2 * k] ** 2 + delta[2 * k + 1] ** 2 for k in range(S)))
            if biggest < 1e-16:
                break
            clipped = biggest > max_step
            if clipped:
                f = max_step / biggest
                delta = [d * f for d in delta]
            x_new = self.project([xi - di for xi, di in zip(x, delta)])
            r_new, J_new, ep_new, eo_new, R_new, p_new = self.evaluate(x_new, tgt)
            cost_new = sum(v * v for v in r_new)
            if cost_new < cost:
                # Gain ratio: actual decrease over the linear model's. For the unclipped
                # step -sol of (A + λI) sol = g the model decrease is gᵀsol + λ|sol|².
                if clipped:
                    Jd = J.dot(delta)
                    predicted = 2.0 * float(g.dot(delta)) - float(Jd.dot(Jd))
                else:
                    gl = g.tolist()
                    predicted = sum(a * b for a, b in zip(gl, delta)) + damping * sum(d * d for d in delta)
                rho = (cost - cost_new) / predicted if predicted > 0.0 else 1.0
                x, r, J, ep, eo, R, p, cost = x_new, r_new, J_new, ep_new, eo_new, R_new, p_new, cost_new
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
            else:
                lam = max(lam, floor) * nu
                nu *= 2.0
                if lam > 1e10 * scale:
                    break
        return Iterate(x, ep, eo, its, R, p)

    CHORD_ITERATIONS = 8
    CHORD_MIN_GAIN = 0.3  # a chord step must shrink the residual norm at least this much

    def _chord(self, x0, tgt, max_step: float) -> ChordIterate:
        """Warm-start fast path: Newton's chord method (Jacobian frozen at the start).

        From a nearby start the frozen Jacobian is accurate to O(distance), so each step
        gains about as many digits as the start was close, at the price of an FK without
        derivatives (~3× cheaper than FK with the Jacobian) and a triangular solve.
        Returns a ``ChordIterate``; when a step does not shrink the
        residual by ``CHORD_MIN_GAIN`` the caller continues with full LM from the result.
        """
        opts = self.options
        stop_p = 1e-2 * opts.position_tolerance
        stop_o = 1e-2 * opts.orientation_tolerance
        x = self.project([float(v) for v in x0])
        r, J, ep, eo, R, p = self.evaluate(x, tgt)
        its = 0
        if ep <= stop_p and eo <= stop_o:
            return ChordIterate(x, r, J, ep, eo, R, p, its, True)
        JT = J.T
        A = JT.dot(J)
        scale = float(A.trace()) / self.n_vars
        A[self._diag] += 1e-12 * scale + 1e-300
        c, info = _dpotrf(A)
        if info != 0:
            return ChordIterate(x, r, J, ep, eo, R, p, its, False)
        norm = math.sqrt(sum(v * v for v in r))
        J0 = J
        while its < self.CHORD_ITERATIONS:
            its += 1
            step, info = _dpotrs(c, JT.dot(r))
            if info != 0:
                break
            delta = step.tolist()
            if max(abs(d) for d in delta) > max_step:
                break
            x_new = self.project([xi - di for xi, di in zip(x, delta)])
            r_new, _, ep_new, eo_new, R_new, p_new = self.evaluate(x_new, tgt, derivatives=False)
            norm_new = math.sqrt(sum(v * v for v in r_new))
            if norm_new > self.CHORD_MIN_GAIN * norm:
                if norm_new < norm:
                    x, r, ep, eo, R, p, norm = x_new, r_new, ep_new, eo_new, R_new, p_new, norm_new
                    J0 = None  # J no longer belongs to x
                break
            x, r, ep, eo, R, p, norm = x_new, r_new, ep_new, eo_new, R_new, p_new, norm_new
            J0 = None
            if ep <= stop_p and eo <= stop_o:
                return ChordIterate(x, r, None, ep, eo, R, p, its, True)
        return ChordIterate(x, r, J0, ep, eo, R, p, its, False)

    def _ok(self, ep: float, eo: float) -> bool:
        return ep <= self.options.position_tolerance and eo <= self.options.orientation_tolerance

    def _weighted(self, ep: float, eo: float) -> float:
        return (self.options.position_weight * ep) ** 2 + (self.options.orientation_weight * eo) ** 2

    # ---------------------------------------------------------------- seeds
    def seed_table(self) -> tuple[Array, Array, Array]:
        """Fixed cold-start configurations (solver variables), their tool positions and rotations."""
        if self._seeds is None:
            rng = np.random.default_rng(self.options.seed)
            N = self.options.seed_table_size
            bounds = np.array(self.bounds)
            if self.phase == "planar":
                X = rng.uniform(-1.0, 1.0, (N, self.S)) * bounds
                X[0] = 0.0
                W = np.empty((N, 2 * self.S))
                W[:, 0::2] = X * self._cpsi
                W[:, 1::2] = X * self._spsi
            else:
                theta = rng.uniform(0.0, 1.0, (N, self.S)) * bounds
                phi = rng.uniform(-np.pi, np.pi, (N, self.S))
                X = np.empty((N, 2 * self.S))
                X[:, 0::2] = theta * np.cos(phi)
                X[:, 1::2] = theta * np.sin(phi)
                X[0] = 0.0
                W = X
            T = kin.forward_kinematics_bending(self.geometry, W, tool_length=self.tool_length)
            self._seeds = (X, T[:, :3, 3], T[:, :3, :3])
        return self._seeds

    def _seed_order(self, target: Array) -> NDArray[np.intp]:
        X, P, R = self.seed_table()
        k1, k2 = self.options.position_weight, self.options.orientation_weight
        score = k1**2 * np.sum((P - target[:3, 3]) ** 2, axis=1)
        if self.orientation == "full":
            score += k2**2 * (3.0 - np.einsum("nij,ij->n", R, target[:3, :3]))
        else:
            score += k2**2 * 2.0 * (1.0 - R[:, :, 2] @ target[:3, 2])
        return np.argsort(score, kind="stable")

    # ---------------------------------------------------------------- public
    def solve(self, target: Array, x0=None, *, fallback: bool = True, max_step: float | None = None,
              max_iterations: int | None = None) -> Solution:
        """Solve for a validated (4, 4) target in the arm frame.

        With ``x0`` the solve is warm-started there; ``fallback`` then allows cold starts
        if the warm start fails.
        """
        tgt = self._prepare(target)
        opts = self.options
        step = opts.max_step_rad if max_step is None else max_step
        iters = opts.max_iterations if max_iterations is None else max_iterations
        total = 0
        best = None
        if x0 is not None:
            x, _, _, ep, eo, R, p, its, done = self._chord(x0, tgt, step)
            total += its
            if not done:
                x, ep, eo, its, R, p = self._lm(x, tgt, max(iters - its, 1), step)
                total += its
            if self._ok(ep, eo):
                return Solution(x, ep, eo, total, True, "converged (warm start)", R, p)
            best = (self._weighted(ep, eo), x, ep, eo, R, p)
            if not fallback:
                return Solution(x, ep, eo, total, False, self._failure_message(target, ep, eo), R, p)
        X = self.seed_table()[0]
        for idx in self._seed_order(target)[: opts.n_starts]:
            x, ep, eo, its, R, p = self._lm(X[idx], tgt, iters, step)
            total += its
            if self._ok(ep, eo):
                return Solution(x, ep, eo, total, True, "converged (cold start)", R, p)
            cand = (self._weighted(ep, eo), x, ep, eo, R, p)
            if best is None or cand[0] < best[0]:
                best = cand
        assert best is not None  # n_starts >= 1 (IKOptions)
        _, x, ep, eo, R, p = best
        return Solution(x, ep, eo, total, False, self._failure_message(target, ep, eo), R, p)

    def _failure_message(self, target: Array, ep: float, eo: float) -> str:
        distance = float(np.linalg.norm(target[:3, 3]))
        where = ""
        if distance > self.reach:
            where = f"outside the workspace: target is {distance:.4f} m from the arm base, beyond the reach {self.reach:.4f} m; "
        return (
            f"{where}unreachable: best residual position error {ep:.3e} m, orientation error {eo:.3e} rad "
            f"(tolerances {self.options.position_tolerance:g} m, {self.options.orientation_tolerance:g} rad)"
        )


_DEFAULT_OPTIONS = IKOptions()


@functools.lru_cache(maxsize=64)
def _cached_solver(geometry: ArmGeometry, orientation: str, phase: str, tool_length: float, plane_angle: float,
                   options: IKOptions) -> IKSolver:
    return IKSolver(geometry, orientation, phase, tool_length, plane_angle, options)  # type: ignore[arg-type]


def get_solver(geometry: ArmGeometry, orientation: Orientation = "full", phase: Phase = "free",
               tool: str | float = 0.0, plane_angle: float = 0.0, options: IKOptions | None = None) -> IKSolver:
    """The (cached) solver for this arm, mode and tool."""
    _check_mode(orientation, phase)
    return _cached_solver(geometry, orientation, phase, tool_length_of(geometry, tool), float(plane_angle),
                          options or _DEFAULT_OPTIONS)


def _validate_q(geometry: ArmGeometry, q: ArrayLike, name: str = "q0") -> Array:
    q = np.asarray(q, dtype=float)
    n = 2 * geometry.n_sections
    if q.shape != (n,):
        raise ValueError(f"{name}: must have {n} entries (θ, φ per section), got shape {q.shape}")
    if not all(map(math.isfinite, q.tolist())):
        raise ValueError(f"{name}: contains NaN or infinite values")
    return q


def _to_arm_frame(target: Array, base: ArrayLike | None) -> Array:
    if base is None:
        return target
    B = validate_pose(base, "base")
    Binv = np.eye(4)
    Binv[:3, :3] = B[:3, :3].T
    Binv[:3, 3] = -B[:3, :3].T @ B[:3, 3]
    return Binv @ target


def solve_ik(
    geometry: ArmGeometry,
    target: ArrayLike,
    orientation: Orientation = "full",
    phase: Phase = "free",
    q0: ArrayLike | None = None,
    *,
    tool: str | float = 0.0,
    base: ArrayLike | None = None,
    plane_angle: float = 0.0,
    options: IKOptions | None = None,
    fallback: bool = True,
) -> IKResult:
    """Configuration ``q`` that puts the tip (or the tool centre point) at ``target``.

    ``target``: (4, 4) pose of the last disk centre (``forward_kinematics``) or, with
    ``tool`` ('grinder', 'gripper' or a length in m), of the tool centre point; in the arm
    base frame, or in the world when ``base`` (the arm's mount pose) is given.
    ``orientation``: 'full' (SO(3)) or 'axis' (tool z only). ``phase``: 'free' or 'planar'
    (every φ in {ψ, ψ+π}, ψ = ``plane_angle``). ``q0``: warm start (else cold multi-start).
    Never returns a wrong ``q`` silently: ``success`` is False unless both errors are
    within the tolerances of ``options``, and ``message`` says why.
    """
    target = validate_pose(target)
    solver = get_solver(geometry, orientation, phase, tool, plane_angle, options)
    x0 = None
    if q0 is not None:
        q0 = _validate_q(geometry, q0)
        last = solver._last
        x0 = last[1] if last is not None and np.array_equal(last[0], q0) else solver.x_from_q(q0)
    arm_target = _to_arm_frame(target, base)
    x, ep, eo, its, ok, msg, R, p = solver.solve(arm_target, x0, fallback=fallback)
    q = solver.q_from_x(x)
    solver._last = (q, x)
    pose = np.array([R[0], R[1], R[2], p[0], R[3], R[4], R[5], p[1], R[6], R[7], R[8], p[2], 0.0, 0.0, 0.0, 1.0]).reshape(4, 4)
    if base is not None:
        pose = np.asarray(base, dtype=float) @ pose
    return IKResult(
        q=q.copy(),
        w=np.array(solver.to_w(x)),
        pose=pose,
        position_error=ep,
        orientation_error=eo,
        success=ok,
        iterations=its,
        message=msg,
    )


# ------------------------------------------------------------------------- paths
def interpolate_pose(A: Array, B: Array, f: float) -> Array:
    """Pose at fraction ``f`` from A to B: position linear, rotation along the geodesic."""
    T = np.eye(4)
    T[:3, 3] = (1.0 - f) * A[:3, 3] + f * B[:3, 3]
    rel = kin.log_so3(A[:3, :3].T @ B[:3, :3])
    T[:3, :3] = A[:3, :3] @ kin.exp_so3(f * rel)
    return T


def unwrap_phases(q: Array, reference: Array, straight_below: float = 1e-9) -> Array:
    """``q`` with each φ moved by 2π multiples to lie within π of ``reference``'s φ.

    A section that is straight (θ below ``straight_below``) keeps the reference phase:
    its phase is undefined and inheriting it avoids a spurious jump.
    """
    out = np.array(q, dtype=float)
    ref = np.asarray(reference, dtype=float)
    for k in range(out.size // 2):
        if out[2 * k] < straight_below:
            out[2 * k + 1] = ref[2 * k + 1]
        else:
            d = out[2 * k + 1] - ref[2 * k + 1]
            out[2 * k + 1] = ref[2 * k + 1] + _wrap(d)
    return out


def step_violations(q_a: Array, q_b: Array, limits: StepLimits) -> list[str]:
    """Which per-section step limits the step q_a → q_b (unwrapped phases) breaks."""
    bad = []
    for k in range(q_a.size // 2):
        dth = abs(q_b[2 * k] - q_a[2 * k])
        if dth > limits.max_dtheta + 1e-12:
            bad.append(f"section {k}: Δθ = {math.degrees(dth):.3f} deg > {limits.max_dtheta_deg:g} deg")
        if min(q_a[2 * k], q_b[2 * k]) >= limits.phase_free_below:
            dph = abs(q_b[2 * k + 1] - q_a[2 * k + 1])
            if dph > limits.max_dphi + 1e-12:
                bad.append(f"section {k}: Δφ = {math.degrees(dph):.3f} deg > {limits.max_dphi_deg:g} deg")
    return bad


def interpolate_q(q_a: ArrayLike, q_b: ArrayLike, fractions: ArrayLike, phase: Phase = "free",
                  phase_free_below: float = math.radians(3.0)) -> Array:
    """Configurations between two solved points (paper eq. 12): (len(fractions), 2S).

    θ and (unwrapped) φ are interpolated linearly, as in eq. 12. Where a section is nearly
    straight at either end (θ < ``phase_free_below``, e.g. a planar section whose θ changes
    sign) the interpolation runs straight in bending coordinates instead, so the bend does
    not swing around through other directions while its phase is meaningless.
    """
    q_a = np.asarray(q_a, dtype=float)
    q_b = np.asarray(q_b, dtype=float)
    f = np.atleast_1d(np.asarray(fractions, dtype=float))[:, None]
    out = (1.0 - f) * q_a + f * q_b
    for k in range(q_a.size // 2):
        ta, tb = q_a[2 * k], q_b[2 * k]
        if min(ta, tb) >= phase_free_below and abs(q_b[2 * k + 1] - q_a[2 * k + 1]) < math.pi / 2:
            continue
        wa = ta * np.array([math.cos(q_a[2 * k + 1]), math.sin(q_a[2 * k + 1])])
        wb = tb * np.array([math.cos(q_b[2 * k + 1]), math.sin(q_b[2 * k + 1])])
        w = (1.0 - f) * wa + f * wb
        theta = np.hypot(w[:, 0], w[:, 1])
        if phase == "planar":
            # φ stays exactly on the plane: φ_a where the bend points along a's direction,
            # else the opposite phase (φ_b when b bends the other way).
            da = np.array([math.cos(q_a[2 * k + 1]), math.sin(q_a[2 * k + 1])])
            db = np.array([math.cos(q_b[2 * k + 1]), math.sin(q_b[2 * k + 1])])
            opposite = q_b[2 * k + 1] if db @ da < 0 else _wrap(q_a[2 * k + 1] + math.pi)
            phi = np.where(w @ da >= 0.0, q_a[2 * k + 1], opposite)
        else:
            raw = np.arctan2(w[:, 1], w[:, 0])
            phi = q_a[2 * k + 1] + (raw - q_a[2 * k + 1] + np.pi) % (2 * np.pi) - np.pi
            phi = np.where(theta < 1e-12, q_a[2 * k + 1], phi)
        out[:, 2 * k] = theta
        out[:, 2 * k + 1] = phi
    return out


@dataclass(frozen=True)
class PathSolution:
    """Solved toolpath: one row per solved point, inserted bisection points included."""

    targets: Array  # (M, 4, 4) in the frame the path was given in
    q: Array  # (M, 2S), phases unwrapped along the path
    position_error: Array  # (M,)
    orientation_error: Array  # (M,)
    iterations: Array  # (M,)
    source: Array  # (M,) position along the input path: integers for input points
    success: bool
    message: str
    failed_index: int = -1  # first input point that failed, -1 if none

    @property
    def original(self) -> NDArray[np.bool_]:
        """Mask of the rows that are input toolpath points (not inserted)."""
        return np.isclose(self.source, np.round(self.source))


def solve_path(
    geometry: ArmGeometry,
    targets: ArrayLike,
    q_start: ArrayLike,
    orientation: Orientation = "full",
    phase: Phase = "free",
    *,
    tool: str | float = 0.0,
    base: ArrayLike | None = None,
    plane_angle: float = 0.0,
    options: IKOptions | None = None,
    limits: StepLimits | None = None,
) -> PathSolution:
    """Follow a toolpath point by point from the configuration ``q_start``.

    Each point is warm-started from the previous solution with the trust radius set by
    the step limits; a step that fails or breaks a limit (a jump to another solution
    branch, a quadrant change of φ) is bisected along the path, up to
    ``limits.max_subdivisions`` times. The first target is reached from ``q_start``'s pose
    the same way, so ``q_start`` may be a nearby configuration (continuation).
    """
    limits = limits or StepLimits()
    solver = get_solver(geometry, orientation, phase, tool, plane_angle, options)
    targets = np.asarray(targets, dtype=float)
    if targets.ndim != 3 or targets.shape[1:] != (4, 4) or targets.shape[0] < 1:
        raise ValueError(f"targets: must be an (N, 4, 4) array of poses with N >= 1 (got shape {targets.shape})")
    for i, T in enumerate(targets):
        validate_pose(T, f"targets[{i}]")
    q_start = _validate_q(geometry, q_start, "q_start")
    arm_targets = np.array([_to_arm_frame(T, base) for T in targets])
    x_prev = solver.x_from_q(q_start).tolist()
    q_prev = q_start.copy()
    if phase == "planar":
        q_prev = solver.q_from_x(x_prev)
    start_pose = np.eye(4)
    R0, p0, _ = solver.kernel.pose_jacobian(solver.to_w(x_prev), False)
    start_pose[:3, :3] = np.array(R0).reshape(3, 3)
    start_pose[:3, 3] = p0
    trust = max(2.0 * limits.max_dtheta, 1e-3)

    rows: list[tuple] = []
    # x, q: the last solution; x_prev, s_prev, s: the one before and the path positions,
    # for a first-order predictor of the next start (the toolpath is smooth).
    state = {"x": x_prev, "q": q_prev, "x_prev": None, "s": None, "s_prev": None}

    def attempt(T: Array, start) -> tuple:
        x, ep, eo, its, ok, msg, _, _ = solver.solve(T, start, fallback=False, max_step=trust)
        q = unwrap_phases(solver.q_from_x(x), state["q"]) if phase == "free" else solver.q_from_x(x)
        if phase == "planar":
            q = _planar_phases(q, state["q"])
        bad = [] if not ok else step_violations(state["q"], q, limits)
        return x, q, ep, eo, its, ok, msg, bad

    def predicted(s_b: float):
        # Only between toolpath points (not from q_start, which may be far: continuation).
        if state["x_prev"] is None or state["s_prev"] is None or state["s_prev"] < 0.0 or state["s"] <= state["s_prev"]:
            return None
        ratio = (s_b - state["s"]) / (state["s"] - state["s_prev"])
        if not 0.0 < ratio <= 2.0:
            return None
        return [a + ratio * (a - b) for a, b in zip(state["x"], state["x_prev"])]

    def follow(A: Array, B: Array, s_a: float, s_b: float, depth: int) -> str | None:
        guess = predicted(s_b)
        result = attempt(B, guess) if guess is not None else None
        if result is None or not result[5] or result[7]:
            result = attempt(B, state["x"])
        x, q, ep, eo, its, ok, msg, bad = result
        if ok and not bad:
            state["x_prev"], state["s_prev"] = state["x"], state["s"]
            state["x"], state["q"], state["s"] = x, q, s_b
            rows.append((B, q, ep, eo, its, s_b))
            return None
        if depth >= limits.max_subdivisions:
            return msg if not ok else "; ".join(bad)
        M = interpolate_pose(A, B, 0.5)
        s_m = 0.5 * (s_a + s_b)
        err = follow(A, M, s_a, s_m, depth + 1)
        if err is not None:
            return err
        return follow(M, B, s_m, s_b, depth + 1)

    previous = start_pose
    message = "ok"
    failed = -1
    for i, T in enumerate(arm_targets):
        err = follow(previous, T, i - 1.0, float(i), 0)
        if err is not None:
            failed = i
            p = targets[i][:3, 3]
            message = (
                f"toolpath point {i} at ({1000 * p[0]:.1f}, {1000 * p[1]:.1f}, {1000 * p[2]:.1f}) mm cannot be "
                f"followed: {err}"
            )
            break
        previous = T
    B = np.eye(4) if base is None else np.asarray(base, dtype=float)
    M = len(rows)
    return PathSolution(
        targets=np.array([B @ r[0] for r in rows]).reshape(M, 4, 4),
        q=np.array([r[1] for r in rows]).reshape(M, 2 * geometry.n_sections),
        position_error=np.array([r[2] for r in rows]),
        orientation_error=np.array([r[3] for r in rows]),
        iterations=np.array([r[4] for r in rows], dtype=int),
        source=np.array([r[5] for r in rows]),
        success=failed < 0,
        message=message,
        failed_index=failed,
    )


def _planar_phases(q: Array, reference: Array) -> Array:
    """Planar q with a straight section keeping the reference phase (still ψ or ψ+π)."""
    out = q.copy()
    for k in range(q.size // 2):
        if out[2 * k] == 0.0:
            out[2 * k + 1] = reference[2 * k + 1]
    return out
