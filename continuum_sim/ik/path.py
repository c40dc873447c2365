"""Solving a toolpath: warm-started IK point by point under per-step limits, and eq. 12 between points.

Paths are solved point by point, warm started, with a per-step box on (Δθ, Δφ) and
bisection of the toolpath where a step would exceed it, so the shape never jumps
quadrant (the defect of the paper's Fig. 9).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import kinematics as kin
from ..configio import require_int, require_range
from ..geometry import ArmGeometry
from .options import Array, IKOptions, Orientation, Phase
from .pose import get_solver
from .problem import wrap_angle
from .targets import to_arm_frame, validate_pose, validate_q


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
            out[2 * k + 1] = ref[2 * k + 1] + wrap_angle(d)
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
            opposite = q_b[2 * k + 1] if db @ da < 0 else wrap_angle(q_a[2 * k + 1] + math.pi)
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
    q_start = validate_q(geometry, q_start, "q_start")
    arm_targets = np.array([to_arm_frame(T, base) for T in targets])
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
