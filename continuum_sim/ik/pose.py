"""Solving one pose: ``solve_ik`` and its result, with the solvers cached per arm, mode and tool."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..geometry import ArmGeometry
from .options import Array, IKOptions, Orientation, Phase, check_mode
from .solver import IKSolver
from .targets import to_arm_frame, tool_length_of, validate_pose, validate_q


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


_DEFAULT_OPTIONS = IKOptions()


@functools.lru_cache(maxsize=64)
def _cached_solver(geometry: ArmGeometry, orientation: str, phase: str, tool_length: float, plane_angle: float,
                   options: IKOptions) -> IKSolver:
    return IKSolver(geometry, orientation, phase, tool_length, plane_angle, options)  # type: ignore[arg-type]


def get_solver(geometry: ArmGeometry, orientation: Orientation = "full", phase: Phase = "free",
               tool: str | float = 0.0, plane_angle: float = 0.0, options: IKOptions | None = None) -> IKSolver:
    """The (cached) solver for this arm, mode and tool."""
    check_mode(orientation, phase)
    return _cached_solver(geometry, orientation, phase, tool_length_of(geometry, tool), float(plane_angle),
                          options or _DEFAULT_OPTIONS)


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
        q0 = validate_q(geometry, q0)
        last = solver.last_solution
        x0 = last[1] if last is not None and np.array_equal(last[0], q0) else solver.x_from_q(q0)
    arm_target = to_arm_frame(target, base)
    x, ep, eo, its, ok, msg, R, p = solver.solve(arm_target, x0, fallback=fallback)
    q = solver.q_from_x(x)
    solver.last_solution = (q, x)
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
