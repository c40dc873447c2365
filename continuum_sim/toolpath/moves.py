"""One arm's timeline pieces: dwells, joint-space transfers and IK-solved Cartesian paths.

Free-space transfers from and to the initial configuration are joint-space moves
(linear in bending coordinates, so the straight arm's undefined phase is harmless);
every move near the plate is a Cartesian toolpath, discretised every
``waypoint_spacing``, solved by warm-started IK under per-step (Δθ, Δφ) limits
(``ik.solve_path``) and interpolated between solved points by paper eq. 12.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import kinematics as kin
from ..geometry import ArmGeometry
from ..ik import get_solver, interpolate_q, solve_path, to_arm_frame
from ..layout import TaskLayout
from ..workspace import UnreachableError
from .config import PlanConfig
from .poses import densify, pose_metric
from .task_plan import STAGE_NAMES
from .timing import trapezoid_duration, trapezoid_position

Array = NDArray[np.float64]


@dataclass
class Move:
    """One piece of one arm's timeline."""

    arm: str
    stage: int
    segment: str
    duration: float
    q_start: Array
    q_end: Array
    phase: str = "free"
    knots_s: Array | None = None  # path metric at each solved waypoint (None: joint move or dwell)
    knots_q: Array | None = None
    distance: float = 0.0
    speed: float = 0.0
    accel: float = 0.0
    gripper_closed: bool = False
    spindle_on: bool = False
    cutting: bool = False
    phase_free_below: float = math.radians(3.0)

    def q_at(self, tau: ArrayLike) -> Array:
        """Configurations at local times ``tau`` ∈ [0, duration]."""
        tau = np.asarray(tau, dtype=float)
        if self.duration <= 0.0 or np.allclose(self.q_start, self.q_end) and self.knots_q is None:
            return np.broadcast_to(self.q_end, tau.shape + self.q_end.shape).copy()
        s = trapezoid_position(tau, self.distance, self.speed, self.accel)
        if self.knots_q is None:  # joint-space move: eq. 12 between the two ends
            f = s / self.distance if self.distance > 0 else np.ones_like(s)
            return interpolate_q(self.q_start, self.q_end, f, self.phase, self.phase_free_below)  # type: ignore[arg-type]
        out = np.empty(tau.shape + (self.q_start.size,))
        idx = np.clip(np.searchsorted(self.knots_s, s, side="right") - 1, 0, len(self.knots_s) - 2)  # type: ignore[arg-type, call-overload]
        for i in np.unique(idx):
            sel = idx == i
            s0, s1 = self.knots_s[i], self.knots_s[i + 1]  # type: ignore[index]
            f = np.clip((s[sel] - s0) / (s1 - s0), 0.0, 1.0) if s1 > s0 else np.ones(int(sel.sum()))
            out[sel] = interpolate_q(self.knots_q[i], self.knots_q[i + 1], f, self.phase, self.phase_free_below)  # type: ignore[arg-type]
        return out


def dwell(arm: str, stage: int, segment: str, q: Array, duration: float, **flags) -> Move:
    return Move(arm, stage, segment, duration, q, q, **flags)


def joint_move(arm: str, stage: int, segment: str, q_a: Array, q_b: Array, cfg: PlanConfig, phase: str, **flags) -> Move:
    """Transfer in bending coordinates; distance = the largest per-section change."""
    wa, wb = kin.to_bending(q_a), kin.to_bending(q_b)
    d = float(np.max(np.hypot(wb[0::2] - wa[0::2], wb[1::2] - wa[1::2])))
    v, a = math.radians(cfg.joint_speed_deg_s), math.radians(cfg.joint_accel_deg_s2)
    return Move(arm, stage, segment, trapezoid_duration(d, v, a), q_a, q_b, phase, distance=d, speed=v, accel=a,
                phase_free_below=cfg.limits.phase_free_below, **flags)


class ArmPlanner:
    """Solves one arm's Cartesian segments in sequence, warm-starting each from the last."""

    def __init__(self, geometry: ArmGeometry, layout: TaskLayout, cfg: PlanConfig, arm: str, orientation: str, phase: str):
        self.geometry, self.layout, self.cfg, self.arm = geometry, layout, cfg, arm
        self.orientation, self.phase = orientation, phase
        self.mount = layout.mount(arm)
        self.base = self.mount.base_transform()
        self.waypoints: dict[str, dict] = {}

    def path_move(self, stage: int, segment: str, poses: list[Array], q_start: Array, speed: float, **flags) -> Move:
        cfg = self.cfg
        targets = densify(poses, cfg.waypoint_spacing, cfg.rotation_radius)
        sol = solve_path(self.geometry, targets, q_start, self.orientation, self.phase, tool=self.mount.tool,  # type: ignore[arg-type]
                         base=self.base, options=cfg.ik, limits=cfg.limits)
        if not sol.success:
            raise UnreachableError(
                "layout", f"{self.arm} arm ({self.mount.tool}), {STAGE_NAMES[stage]}/{segment}: {sol.message}")
        s = np.concatenate([[0.0], np.cumsum([pose_metric(a, b, cfg.rotation_radius)
                                              for a, b in zip(sol.targets[:-1], sol.targets[1:])])])
        self.waypoints[f"{self.arm}/{segment}"] = {
            "q": sol.q,
            "targets": sol.targets,
            "position_error": sol.position_error,
            "orientation_error": sol.orientation_error,
            "source": sol.source,
            "stage": STAGE_NAMES[stage],
        }
        distance = float(s[-1])
        return Move(self.arm, stage, segment, trapezoid_duration(distance, speed, cfg.max_accel), sol.q[0], sol.q[-1],
                    self.phase, knots_s=s, knots_q=sol.q, distance=distance, speed=speed, accel=cfg.max_accel,
                    phase_free_below=cfg.limits.phase_free_below, **flags)

    def nearest_solution(self, pose: Array, q_ref: Array) -> Array:
        """IK of ``pose`` among the cold-start solutions, the one nearest ``q_ref`` in bending coordinates."""
        cfg = self.cfg
        solver = get_solver(self.geometry, self.orientation, self.phase, self.mount.tool, 0.0, cfg.ik)  # type: ignore[arg-type]
        best = None
        for x in solver.cold_solutions(to_arm_frame(pose, self.base), max(cfg.ik.n_starts, 24)):
            q = solver.q_from_x(x)
            d = float(np.sum((kin.to_bending(q) - kin.to_bending(q_ref)) ** 2))
            if best is None or d < best[0] - 1e-12:
                best = (d, q)
        if best is None:  # pragma: no cover - check_poses ran first
            raise UnreachableError("layout", f"{self.arm} arm: no IK solution for a key pose")
        return best[1]
