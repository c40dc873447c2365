"""Toolpaths and the timed plan of the sample-removal task (SPEC §5; paper §4.2, §5.2).

Stages (``STAGE_NAMES``): 1 initial, 2 clamping (the gripper approaches the sample's side
edge and closes), 3 milling (the grinder's approach → cutting → exit → return, spindle on,
vertical = plate normal, slow feed on the cut), 4 retrieval (the gripper carries the sample
away), 5 return (the grinder goes back to its initial configuration). One arm moves at a
time; the other holds its configuration.

Free-space transfers from and to the initial configuration are joint-space moves
(linear in bending coordinates, so the straight arm's undefined phase is harmless);
every move near the plate is a Cartesian toolpath, discretised every
``waypoint_spacing``, solved by warm-started IK under per-step (Δθ, Δφ) limits
(``ik.solve_path``) and interpolated between solved points by paper eq. 12. Timing:
trapezoidal speed profiles along the path (feed speed per segment). The plan is refused
(``UnreachableError``, a ``ConfigError``) if a pose is outside an arm's workspace or a
path cannot be followed, naming the first offending point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from . import kinematics as kin
from .configio import ConfigError, atomic_write_bytes, require_positive, require_range
from .distances import polyline_distance
from .geometry import ArmGeometry
from .ik import IKOptions, StepLimits, _to_arm_frame, get_solver, interpolate_pose, interpolate_q, solve_ik, solve_path
from .layout import TaskLayout
from .workspace import UnreachableError, check_poses

Array = NDArray[np.float64]

STAGE_NAMES = ("initial", "clamping", "milling", "retrieval", "return")
SEGMENT_NAMES = ("hold", "approach", "grasp", "close", "spin_up", "cutting", "exit", "return", "carry", "final")


# ------------------------------------------------------------------------ config
@dataclass(frozen=True)
class PlanConfig:
    """How the task is planned: speeds, dwells, step limits, IK modes, path shapes."""

    sample_rate_hz: float = 100.0
    cut_speed: float = 0.005  # m/s, feed along the kerf
    fast_speed: float = 0.040  # m/s, every other Cartesian move
    max_accel: float = 0.2  # m/s², trapezoidal speed profile of the tool point
    rotation_radius: float = 0.1  # m/rad: a tool rotation counts as this much path length for timing
    joint_speed_deg_s: float = 20.0  # joint-space transfers: bending-coordinate speed per section
    joint_accel_deg_s2: float = 40.0
    waypoint_spacing: float = 0.002  # m between IK-solved toolpath points
    dwell_initial: float = 0.5  # s
    dwell_close: float = 1.0  # s, gripper closing on the plate
    dwell_spin_up: float = 1.0  # s, spindle reaching speed before the approach
    dwell_final: float = 0.5  # s
    dwell_before_cut: float = 1.5  # s, the grinder settles at the cut start (in air) before feeding
    lead_in: float = 0.012  # m: the cut starts this far outside the front edge (> kerf_width/2)
    lead_out: float = 0.020  # m: and ends this far beyond the side edge, where the grinder waits while the sample is carried off
    approach_length: float = 0.020  # m: horizontal approach toward the front edge before the cut start
    pregrasp_distance: float = 0.035  # m: the gripper backs off along its tool axis before the grasp
    # m, world: sample carried away (stage 4), mostly sideways (-y) so it clears the grinder
    # housing that waits beyond the side edge, below the plate ((0.04, -0.03, -0.05) grazed it)
    carry_offset: tuple[float, float, float] = (0.02, -0.09, -0.03)
    return_offset: float = 0.004  # m: the grinder returns this far inside the freed sample area, clear of the kerf's outer wall
    q_left_initial_deg: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    q_right_initial_deg: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    grinder_phase: Literal["free", "planar"] = "free"  # the grinder's tool roll is free: 'axis' orientation
    gripper_phase: Literal["free", "planar"] = "free"  # the gripper needs 'full' orientation
    limits: StepLimits = field(default_factory=StepLimits)
    ik: IKOptions = field(default_factory=IKOptions)
    grinder_radius: float = 0.015  # m, collision envelope of the grinder housing (the cutter: kerf_width/2)
    grinder_cutter_length: float = 0.020  # m, the cutter's exposed length below the TCP (the rest is housing)
    gripper_radius: float = 0.012  # m, collision spheres of the gripper (palm, fingers, pads)
    gripper_half_width: float = 0.014  # m, offset of the outer gripper spheres along the tool x (open jaws)
    min_clearance: float = 0.003  # m: plans with less arm-to-arm clearance are refused
    progress: bool = False  # tqdm progress bars

    def __post_init__(self) -> None:
        require_range("sample_rate_hz", self.sample_rate_hz, 1.0, 10_000.0, low_inclusive=True)
        require_range("cut_speed", self.cut_speed, 0.0, 0.5)
        require_range("fast_speed", self.fast_speed, 0.0, 1.0)
        require_range("max_accel", self.max_accel, 0.0, 100.0)
        require_range("rotation_radius", self.rotation_radius, 0.0, 10.0, low_inclusive=True)
        require_range("joint_speed_deg_s", self.joint_speed_deg_s, 0.0, 3600.0)
        require_range("joint_accel_deg_s2", self.joint_accel_deg_s2, 0.0, 1e5)
        require_range("waypoint_spacing", self.waypoint_spacing, 1e-4, 0.05, low_inclusive=True)
        for name in ("dwell_initial", "dwell_close", "dwell_spin_up", "dwell_final", "dwell_before_cut"):
            require_range(name, getattr(self, name), 0.0, 600.0, low_inclusive=True)
        require_range("lead_in", self.lead_in, 0.0, 0.2)
        require_range("lead_out", self.lead_out, 0.0, 0.2)
        require_range("approach_length", self.approach_length, 0.0, 0.2, low_inclusive=True)
        require_range("pregrasp_distance", self.pregrasp_distance, 0.0, 0.3)
        require_range("return_offset", self.return_offset, 0.0, 0.05, low_inclusive=True)
        for i, v in enumerate(self.carry_offset):
            require_range(f"carry_offset[{i}]", v, -0.5, 0.5, low_inclusive=True)
        for name in ("q_left_initial_deg", "q_right_initial_deg"):
            q = getattr(self, name)
            if len(q) != 6:
                raise ConfigError(name, f"must have 6 entries (θ, φ per section; got {len(q)})")
            for k in range(3):
                require_range(f"{name}[{2 * k}]", q[2 * k], 0.0, 90.0, low_inclusive=True)
                require_range(f"{name}[{2 * k + 1}]", q[2 * k + 1], -360.0, 360.0, low_inclusive=True)
        for name in ("grinder_phase", "gripper_phase"):
            if getattr(self, name) not in ("free", "planar"):
                raise ConfigError(name, f"must be 'free' or 'planar' (got {getattr(self, name)!r})")
        require_positive("grinder_radius", self.grinder_radius)
        require_positive("gripper_radius", self.gripper_radius)
        require_range("grinder_cutter_length", self.grinder_cutter_length, 0.0, 0.5, low_inclusive=True)
        require_range("gripper_half_width", self.gripper_half_width, 0.0, 0.2, low_inclusive=True)
        require_range("min_clearance", self.min_clearance, -1.0, 1.0)

    def q_initial(self, arm: str) -> Array:
        return np.radians(self.q_left_initial_deg if arm == "left" else self.q_right_initial_deg)


# ------------------------------------------------------------------------ result
@dataclass(frozen=True)
class TaskPlan:
    """The timed plan both arms follow, sampled at ``sample_rate_hz`` (SPEC §5).

    Arrays share their first dimension N (samples). ``tcp_*`` are the planned world poses
    of the tool centre points: FK of the planned ``q_*`` (exactly what the shapes give).
    ``cut_path`` holds the ideal cutting toolpath and ``waypoints`` the IK-solved points
    per path segment, with their errors, for the paper-style plots.
    """

    t: Array
    stage: NDArray[np.int64]  # index into STAGE_NAMES
    segment: NDArray[np.int64]  # index into SEGMENT_NAMES
    q_left: Array
    q_right: Array
    tcp_left: Array
    tcp_right: Array
    gripper_closed: NDArray[np.bool_]
    spindle_on: NDArray[np.bool_]
    cutting: NDArray[np.bool_]
    waypoints: dict  # "<arm>/<segment>" -> dict(q, targets, position_error, orientation_error, source)
    metrics: dict
    stage_names: tuple[str, ...] = STAGE_NAMES
    segment_names: tuple[str, ...] = SEGMENT_NAMES

    @property
    def n(self) -> int:
        return int(self.t.size)

    def q(self, arm: str) -> Array:
        """(N, 6) planned configurations of ``arm``."""
        return self.q_left if arm == "left" else self.q_right if arm == "right" else _unknown_arm(arm)

    def tcp(self, arm: str) -> Array:
        """(N, 4, 4) planned world tool-centre poses of ``arm``."""
        return self.tcp_left if arm == "left" else self.tcp_right if arm == "right" else _unknown_arm(arm)

    def stage_mask(self, name: str) -> NDArray[np.bool_]:
        return self.stage == self.stage_names.index(name)


def _unknown_arm(arm: str) -> Array:
    raise KeyError(f"the plan has no arm {arm!r}")


# ------------------------------------------------------------------------ timing
def trapezoid_duration(distance: float, v: float, a: float) -> float:
    """Time to cover ``distance`` from rest to rest with speed ≤ v and acceleration ≤ a."""
    if distance <= 0.0:
        return 0.0
    if distance >= v * v / a:
        return distance / v + v / a
    return 2.0 * math.sqrt(distance / a)


def trapezoid_position(t: Array, distance: float, v: float, a: float) -> Array:
    """Distance covered at times ``t`` along the rest-to-rest trapezoidal profile."""
    t = np.asarray(t, dtype=float)
    if distance <= 0.0:
        return np.zeros_like(t)
    T = trapezoid_duration(distance, v, a)
    vp = min(v, math.sqrt(distance * a))  # peak speed
    ta = vp / a
    s = np.where(
        t < ta,
        0.5 * a * t**2,
        np.where(t <= T - ta, 0.5 * a * ta**2 + vp * (t - ta), distance - 0.5 * a * np.clip(T - t, 0.0, None) ** 2),
    )
    return np.clip(s, 0.0, distance)


# ------------------------------------------------------------------------ moves
@dataclass
class _Move:
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

    def q_at(self, tau: Array) -> Array:
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


def _dwell(arm: str, stage: int, segment: str, q: Array, duration: float, **flags) -> _Move:
    return _Move(arm, stage, segment, duration, q, q, **flags)


def _joint_move(arm: str, stage: int, segment: str, q_a: Array, q_b: Array, cfg: PlanConfig, phase: str, **flags) -> _Move:
    """Transfer in bending coordinates; distance = the largest per-section change."""
    wa, wb = kin.to_bending(q_a), kin.to_bending(q_b)
    d = float(np.max(np.hypot(wb[0::2] - wa[0::2], wb[1::2] - wa[1::2])))
    v, a = math.radians(cfg.joint_speed_deg_s), math.radians(cfg.joint_accel_deg_s2)
    return _Move(arm, stage, segment, trapezoid_duration(d, v, a), q_a, q_b, phase, distance=d, speed=v, accel=a,
                 phase_free_below=cfg.limits.phase_free_below, **flags)


def densify(poses: list[Array], spacing: float, rotation_radius: float) -> Array:
    """Straight segments between the given poses, split so no step exceeds ``spacing``."""
    out = [poses[0]]
    for A, B in zip(poses[:-1], poses[1:]):
        d = _pose_metric(A, B, rotation_radius)
        n = max(1, int(math.ceil(d / spacing - 1e-9)))
        out += [interpolate_pose(A, B, (i + 1) / n) for i in range(n)]
    return np.array(out)


def _pose_metric(A: Array, B: Array, rotation_radius: float) -> float:
    rot = float(np.linalg.norm(kin.log_so3(A[:3, :3].T @ B[:3, :3])))
    return max(float(np.linalg.norm(B[:3, 3] - A[:3, 3])), rotation_radius * rot)


class _ArmPlanner:
    """Solves one arm's Cartesian segments in sequence, warm-starting each from the last."""

    def __init__(self, geometry: ArmGeometry, layout: TaskLayout, cfg: PlanConfig, arm: str, orientation: str, phase: str):
        self.geometry, self.layout, self.cfg, self.arm = geometry, layout, cfg, arm
        self.orientation, self.phase = orientation, phase
        self.mount = layout.mount(arm)
        self.base = self.mount.base_transform()
        self.waypoints: dict[str, dict] = {}

    def path_move(self, stage: int, segment: str, poses: list[Array], q_start: Array, speed: float, **flags) -> _Move:
        cfg = self.cfg
        targets = densify(poses, cfg.waypoint_spacing, cfg.rotation_radius)
        sol = solve_path(self.geometry, targets, q_start, self.orientation, self.phase, tool=self.mount.tool,  # type: ignore[arg-type]
                         base=self.base, options=cfg.ik, limits=cfg.limits)
        if not sol.success:
            raise UnreachableError(
                "layout", f"{self.arm} arm ({self.mount.tool}), {STAGE_NAMES[stage]}/{segment}: {sol.message}")
        s = np.concatenate([[0.0], np.cumsum([_pose_metric(a, b, cfg.rotation_radius)
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
        return _Move(self.arm, stage, segment, trapezoid_duration(distance, speed, cfg.max_accel), sol.q[0], sol.q[-1],
                     self.phase, knots_s=s, knots_q=sol.q, distance=distance, speed=speed, accel=cfg.max_accel,
                     phase_free_below=cfg.limits.phase_free_below, **flags)


# ------------------------------------------------------------------------ toolpaths
def grinder_poses(layout: TaskLayout, cfg: PlanConfig) -> dict[str, Array]:
    """Key world poses of the grinder TCP, all with the spindle along +z (the plate normal).

    The vertical spindle keeps the grinder on a thin ring of reach around its base (its
    TCP height range at a given distance is only ~6 cm), so every move near the plate is
    horizontal at the cutting height: approach toward the front edge from outside, cut,
    leave beyond the side edge, wait there while the sample is carried off, and return
    along the (now empty) kerf, shifted into the freed sample area, to the start.
    """
    plate = layout.plate
    kerf = plate.kerf_polyline()
    z = plate.top_z + plate.cut_overtravel

    def pose(x, y):
        T = np.eye(4)
        T[:3, 3] = (x, y, z)
        return T

    x_in, y_in = kerf[1, 0], kerf[1, 1]
    y_start = plate.corner_y - cfg.lead_in
    # The way back, once the sample is gone: the kerf's centre line moved toward the freed
    # sample area, so the cutter (exactly one kerf wide) does not rub the remaining wall.
    xr, yr = x_in + cfg.return_offset, y_in - cfg.return_offset
    return {
        "pre_cut": pose(x_in, y_start - cfg.approach_length),
        "cut_start": pose(x_in, y_start),
        "front_edge": pose(x_in, plate.corner_y),
        "inner_corner": pose(x_in, y_in),
        "side_edge": pose(plate.corner_x, y_in),
        "cut_end": pose(plate.corner_x + cfg.lead_out, y_in),
        "return_out": pose(plate.corner_x + cfg.lead_out, yr),
        "return_side": pose(plate.corner_x, yr),
        "return_corner": pose(xr, yr),
        "return_front": pose(xr, plate.corner_y),
        "return_start": pose(xr, y_start - cfg.approach_length),
    }


def gripper_poses(layout: TaskLayout, cfg: PlanConfig) -> dict[str, Array]:
    """Key world poses of the gripper TCP: pre-grasp (backed off along the tool axis), grasp, carried."""
    grasp = layout.grasp_pose()
    pre = grasp.copy()
    pre[:3, 3] -= cfg.pregrasp_distance * grasp[:3, 2]
    carried = grasp.copy()
    carried[:3, 3] += np.asarray(cfg.carry_offset)
    return {"pre_grasp": pre, "grasp": grasp, "carried": carried}


def _nearest_solution(planner: _ArmPlanner, pose: Array, q_ref: Array, cfg: PlanConfig) -> Array:
    """IK of ``pose`` among the cold-start solutions, the one nearest ``q_ref`` in bending coordinates."""
    solver = get_solver(planner.geometry, planner.orientation, planner.phase, planner.mount.tool, 0.0, cfg.ik)  # type: ignore[arg-type]
    target = _to_arm_frame(pose, planner.base)
    X = solver.seed_table()[0]
    best = None
    for idx in solver._seed_order(target)[: max(cfg.ik.n_starts, 24)]:
        x, ep, eo, its, R, p = solver._lm(X[idx], solver._prepare(target), cfg.ik.max_iterations, cfg.ik.max_step_rad)
        if not solver._ok(ep, eo):
            continue
        q = solver.q_from_x(x)
        d = float(np.sum((kin.to_bending(q) - kin.to_bending(q_ref)) ** 2))
        if best is None or d < best[0] - 1e-12:
            best = (d, q)
    if best is None:  # pragma: no cover - check_poses ran first
        raise UnreachableError("layout", f"{planner.arm} arm: no IK solution for a key pose")
    return best[1]


# ------------------------------------------------------------------------ the plan
def plan_task(geometry: ArmGeometry, layout: TaskLayout, cfg: PlanConfig | None = None) -> TaskPlan:
    """The timed dual-arm plan of the sample-removal task (SPEC §5).

    Raises ``UnreachableError`` (a ``ConfigError``) naming the first pose or toolpath
    point an arm cannot reach, or the moment the arms come closer than ``min_clearance``.
    """
    cfg = cfg or PlanConfig()
    gp = grinder_poses(layout, cfg)
    hp = gripper_poses(layout, cfg)
    # Reachability of every key pose first: the clearest message for a bad layout.
    check_poses(geometry, layout, "left", [(f"grinder {k.replace('_', ' ')}", v) for k, v in gp.items()], "axis",
                cfg.grinder_phase, cfg.ik)
    check_poses(geometry, layout, "right", [(f"gripper {k.replace('_', ' ')}", v) for k, v in hp.items()], "full",
                cfg.gripper_phase, cfg.ik)

    grinder = _ArmPlanner(geometry, layout, cfg, "left", "axis", cfg.grinder_phase)
    gripper = _ArmPlanner(geometry, layout, cfg, "right", "full", cfg.gripper_phase)
    qL0, qR0 = cfg.q_initial("left"), cfg.q_initial("right")
    S = {name: i for i, name in enumerate(STAGE_NAMES)}
    timeline: list[tuple[int, list[_Move]]] = []  # (stage, moves of the active arm)

    steps = tqdm(total=5, desc="planning", disable=not cfg.progress)
    # 1 initial
    timeline.append((S["initial"], [_dwell("left", S["initial"], "hold", qL0, cfg.dwell_initial)]))
    steps.update()
    # 2 clamping: joint transfer to the pre-grasp shape, Cartesian grasp, close.
    q_pre = _nearest_solution(gripper, hp["pre_grasp"], qR0, cfg)
    m_app = _joint_move("right", S["clamping"], "approach", qR0, q_pre, cfg, gripper.phase)
    m_grasp = gripper.path_move(S["clamping"], "grasp", [hp["pre_grasp"], hp["grasp"]], q_pre, cfg.fast_speed / 2)
    m_close = _dwell("right", S["clamping"], "close", m_grasp.q_end, cfg.dwell_close, gripper_closed=True)
    timeline.append((S["clamping"], [m_app, m_grasp, m_close]))
    steps.update()
    # 3 milling: joint transfer to the pre-cut shape, then horizontal moves at the cutting height.
    q_cut = _nearest_solution(grinder, gp["pre_cut"], qL0, cfg)
    spin = dict(spindle_on=True)
    kerf = [gp[k] for k in ("cut_start", "front_edge", "inner_corner", "side_edge")]
    m_spin = _dwell("left", S["milling"], "spin_up", qL0, cfg.dwell_spin_up, **spin)
    m_tr = _joint_move("left", S["milling"], "approach", qL0, q_cut, cfg, grinder.phase, **spin)
    m_app = grinder.path_move(S["milling"], "approach", [gp["pre_cut"], gp["cut_start"]], q_cut, cfg.fast_speed, **spin)
    m_settle = _dwell("left", S["milling"], "approach", m_app.q_end, cfg.dwell_before_cut, **spin)
    m_cut = grinder.path_move(S["milling"], "cutting", kerf, m_app.q_end, cfg.cut_speed, cutting=True, **spin)
    m_exit = grinder.path_move(S["milling"], "exit", [gp["side_edge"], gp["cut_end"]], m_cut.q_end, cfg.fast_speed, **spin)
    timeline.append((S["milling"], [m_spin, m_tr, m_app, m_settle, m_cut, m_exit]))
    steps.update()
    # 4 retrieval: the grinder waits beyond the side edge while the sample is carried off
    # (returning along the kerf first brushed the freed sample, which still sat beside it).
    m_carry = gripper.path_move(S["retrieval"], "carry", [hp["grasp"], hp["carried"]], m_close.q_end, cfg.fast_speed,
                                gripper_closed=True)
    timeline.append((S["retrieval"], [m_carry]))
    steps.update()
    # 5 return: the grinder back along the empty kerf (spindle off), then home.
    back = [gp[k] for k in ("cut_end", "return_out", "return_side", "return_corner", "return_front", "return_start")]
    m_ret = grinder.path_move(S["return"], "return", back, m_exit.q_end, cfg.fast_speed)
    m_back = _joint_move("left", S["return"], "return", m_ret.q_end, qL0, cfg, grinder.phase)
    m_final = _dwell("left", S["return"], "final", qL0, cfg.dwell_final)
    timeline.append((S["return"], [m_ret, m_back, m_final]))
    steps.update()
    steps.close()

    plan = _sample(geometry, layout, cfg, timeline, qL0, qR0, {**grinder.waypoints, **gripper.waypoints})
    m = plan.metrics
    for name, path, what in (("arm", "layout", "the arms come within {} of each other"),
                              ("sample", "plan.carry_offset", "the carried sample comes within {} of the grinder arm")):
        if m[f"min_{name}_clearance_m"] < cfg.min_clearance:
            raise UnreachableError(
                path,
                what.format(f"{1000 * m[f'min_{name}_clearance_m']:.1f} mm")
                + f" (less than min_clearance {1000 * cfg.min_clearance:.1f} mm) at t = {m[f'min_{name}_clearance_t']:.2f} s"
                f" during {m[f'min_{name}_clearance_stage']}",
            )
    return plan


MAX_PLAN_SAMPLES = 100_000  # timed plan samples (default: 5,134); ~4 kB each while planning (docs/errors.md "Limits")


def check_plan_samples(n_samples: int, duration_s: float, rate_hz: float, longest: str) -> None:
    """The plan's sample count, known from its move durations before any array is allocated."""
    if n_samples > MAX_PLAN_SAMPLES:
        raise ConfigError(
            "plan",
            f"the plan would last {duration_s:.4g} s = {n_samples} samples at sample_rate_hz = {rate_hz:g}; at most "
            f"{MAX_PLAN_SAMPLES} allowed (longest move: {longest}; raise plan.cut_speed / plan.fast_speed, shorten the "
            "dwells or lower plan.sample_rate_hz)",
        )


def _sample(geometry, layout, cfg, timeline, qL0, qR0, waypoints) -> TaskPlan:
    """Lay the stages end to end and sample both arms at the plan rate."""
    dt = 1.0 / cfg.sample_rate_hz
    # Refuse an absurd plan (a 1e-7 m/s cut: 10^8 samples, gigabytes) before allocating it.
    moves = [mv for _, stage_moves in timeline for mv in stage_moves]
    n_total = 1 + sum(max(1, round(mv.duration / dt)) if mv.duration > 0 else 0 for mv in moves)
    longest = max(moves, key=lambda mv: mv.duration)
    check_plan_samples(n_total, n_total * dt, cfg.sample_rate_hz, f"{longest.segment} of the {longest.arm} arm, {longest.duration:.4g} s")
    last = {"left": qL0, "right": qR0}
    closed = False
    t0 = 0.0
    chunks = []
    for stage, moves in timeline:
        for mv in moves:
            n = max(1, int(round(mv.duration / dt))) if mv.duration > 0 else 0
            if n == 0:
                last[mv.arm] = mv.q_end
                continue
            q_active = mv.q_at(np.arange(1, n + 1) * (mv.duration / n))
            other = "right" if mv.arm == "left" else "left"
            q_other = np.broadcast_to(last[other], q_active.shape)
            closed = closed or mv.gripper_closed
            chunks.append({
                "t": t0 + np.arange(1, n + 1) * dt,
                "stage": np.full(n, stage),
                "segment": np.full(n, SEGMENT_NAMES.index(mv.segment)),
                "left": q_active if mv.arm == "left" else q_other,
                "right": q_active if mv.arm == "right" else q_other,
                "closed": np.full(n, closed),
                "spindle": np.full(n, mv.spindle_on),
                "cutting": np.full(n, mv.cutting),
            })
            t0 += n * dt
            last[mv.arm] = mv.q_end
    first = {
        "t": np.zeros(1), "stage": np.zeros(1, int), "segment": np.zeros(1, int), "left": qL0[None], "right": qR0[None],
        "closed": np.zeros(1, bool), "spindle": np.zeros(1, bool), "cutting": np.zeros(1, bool),
    }
    chunks.insert(0, first)
    cat = {k: np.concatenate([c[k] for c in chunks]) for k in first}
    q_left, q_right = _continuous_phases(cat["left"]), _continuous_phases(cat["right"])
    bl, br = layout.left.base_transform(), layout.right.base_transform()
    tcp_left = kin.tool_centre_pose(geometry, q_left, layout.left.tool, base=bl)
    tcp_right = kin.tool_centre_pose(geometry, q_right, layout.right.tool, base=br)
    metrics = _metrics(geometry, layout, cfg, cat, q_left, q_right, tcp_left, tcp_right, waypoints)
    return TaskPlan(
        t=cat["t"], stage=cat["stage"].astype(np.int64), segment=cat["segment"].astype(np.int64), q_left=q_left,
        q_right=q_right, tcp_left=tcp_left, tcp_right=tcp_right, gripper_closed=cat["closed"],
        spindle_on=cat["spindle"], cutting=cat["cutting"], waypoints=waypoints, metrics=metrics,
    )


def _continuous_phases(q: Array) -> Array:
    """Phase unwrapping along the samples; a straight section (θ = 0) takes the phase of
    the nearest bent sample before it (or after it, at the start), so φ does not jump
    where it is undefined."""
    q = q.copy()
    for k in range(q.shape[1] // 2):
        phi = q[:, 2 * k + 1]
        bent = q[:, 2 * k] > 1e-12
        if not bent.any():
            continue
        idx = np.where(bent, np.arange(len(phi)), 0)
        np.maximum.accumulate(idx, out=idx)
        first = int(np.argmax(bent))
        idx[:first] = first
        q[:, 2 * k + 1] = np.unwrap(phi[idx])
    return q


# ------------------------------------------------------------------------ checks
def _disk_radii(geometry: ArmGeometry) -> Array:
    return np.concatenate([[geometry.sections[0].disk_diameter / 2]]
                          + [np.full(s.n_segments, s.disk_diameter / 2) for s in geometry.sections])


def arm_envelope(geometry: ArmGeometry, layout: TaskLayout, cfg: PlanConfig, arm: str, q: Array) -> tuple[Array, Array]:
    """Collision spheres of an arm: (..., K, 3) centres and (K,) radii.

    Disks: a sphere of the disk radius at every disk centre. Grinder: housing spheres
    along the tool axis, the cutter (kerf_width/2) at the TCP end. Gripper: three rows of
    spheres across the tool x (palm, fingers and pads, jaws open) along the tool axis.
    """
    mount = layout.mount(arm)
    frames = kin.disk_frames(geometry, q, mount.base_transform())
    centres = [frames[..., :3, 3]]
    radii = [_disk_radii(geometry)]
    tip = frames[..., -1, :, :]
    length = geometry.tools.length(mount.tool)
    if mount.tool == "grinder":
        housing = max(length - cfg.grinder_cutter_length, 0.0)
        d = np.concatenate([np.linspace(0.0, housing, 4)[1:], np.linspace(housing, length, 3)[1:]])
        r = np.array([cfg.grinder_radius] * 3 + [layout.plate.kerf_width / 2] * 2)
        centres.append(tip[..., None, :3, 3] + d[:, None] * tip[..., None, :3, 2])
        radii.append(r)
    else:
        f = np.array([0.3, 0.55, 0.8, 1.0])
        for lateral in (-cfg.gripper_half_width, 0.0, cfg.gripper_half_width):
            centres.append(tip[..., None, :3, 3] + (length * f)[:, None] * tip[..., None, :3, 2]
                           + lateral * tip[..., None, :3, 0])
            radii.append(np.full(f.size, cfg.gripper_radius))
    return np.concatenate(centres, axis=-2), np.concatenate(radii)


def sample_box_gaps(geometry: ArmGeometry, layout: TaskLayout, cfg: PlanConfig, q_left: Array, tcp_right: Array) -> Array:
    """Per sample, the gap between the grinder arm's envelope spheres and the carried sample.

    The sample is a box that keeps its planned pose relative to the gripper's tool centre
    (the grasp); a sphere's gap to it is |max(|p_local| − half-size, 0)| − r, exact.
    """
    plate = layout.plate
    grasp = layout.grasp_pose()
    rel_pos = grasp[:3, :3].T @ (plate.sample_centre - grasp[:3, 3])  # sample centre in the tool-centre frame
    rel_rot = grasp[:3, :3].T  # the sample's axes (the world's, at the grasp) in the tool-centre frame
    half = np.array([plate.sample_x, plate.sample_y, plate.thickness]) / 2
    centre = tcp_right[..., :3, :3] @ rel_pos + tcp_right[..., :3, 3]  # (N, 3)
    rot = tcp_right[..., :3, :3] @ rel_rot  # (N, 3, 3): sample axes in the world
    pl, rl = arm_envelope(geometry, layout, cfg, "left", q_left)
    local = np.einsum("nji,nkj->nki", rot, pl - centre[:, None, :])  # sphere centres in the sample frame
    outside = np.maximum(np.abs(local) - half, 0.0)
    return np.min(np.linalg.norm(outside, axis=-1) - rl[None, :], axis=1)


def _min_sphere_gaps(pa: Array, ra: Array, pb: Array, rb: Array) -> Array:
    """Per sample, the smallest surface gap between two sphere sets (..., A, 3) and (..., B, 3)."""
    out = np.empty(len(pa))
    radii = ra[:, None] + rb[None, :]
    for start in range(0, len(pa), 500):
        a, b = pa[start:start + 500], pb[start:start + 500]
        # |a - b|² = |a|² + |b|² - 2 a·b: one batched matmul instead of an (n, na, nb, 3) difference.
        d2 = np.einsum("nid,nid->ni", a, a)[:, :, None] + np.einsum("njd,njd->nj", b, b)[:, None, :] - 2.0 * a @ b.transpose(0, 2, 1)
        out[start:start + 500] = np.min(np.sqrt(np.maximum(d2, 0.0)) - radii, axis=(1, 2))
    return out


def arm_clearance(geometry: ArmGeometry, layout: TaskLayout, cfg: PlanConfig, q_left: Array, q_right: Array) -> Array:
    """Smallest surface distance between the two arms' envelopes per sample (negative: overlap)."""
    pl, rl = arm_envelope(geometry, layout, cfg, "left", q_left)
    pr, rr = arm_envelope(geometry, layout, cfg, "right", q_right)
    return _min_sphere_gaps(pl, rl, pr, rr)




def plate_clearance(geometry: ArmGeometry, layout: TaskLayout, q: Array, arm: str) -> Array:
    """Smallest distance from an arm's disks (as spheres) to the plate box, per sample; tools excluded."""
    plate = layout.plate
    lo = np.array([plate.corner_x - plate.size[0], plate.corner_y, plate.top_z - plate.thickness])
    hi = np.array([plate.corner_x, plate.corner_y + plate.size[1], plate.top_z])
    frames = kin.disk_frames(geometry, q, layout.mount(arm).base_transform())
    c = frames[..., :3, 3]
    radii = _disk_radii(geometry)
    d = np.linalg.norm(np.maximum(np.maximum(lo - c, c - hi), 0.0), axis=-1) - radii
    return d.min(axis=-1)


def _closest(name: str, gaps: Array, samples: Array, cat: dict) -> dict:
    """``min_<name>_clearance_m`` / ``_t`` / ``_stage`` of the smallest gap (gaps[i] at plan sample samples[i])."""
    if gaps.size == 0:
        return {f"min_{name}_clearance_m": math.inf, f"min_{name}_clearance_t": None, f"min_{name}_clearance_stage": None}
    j = int(np.argmin(gaps))
    k = int(samples[j])
    return {
        f"min_{name}_clearance_m": float(gaps[j]),
        f"min_{name}_clearance_t": float(cat["t"][k]),
        f"min_{name}_clearance_stage": STAGE_NAMES[int(cat["stage"][k])] + "/" + SEGMENT_NAMES[int(cat["segment"][k])],
    }


def _metrics(geometry, layout, cfg, cat, q_left, q_right, tcp_left, tcp_right, waypoints) -> dict:
    clearance = arm_clearance(geometry, layout, cfg, q_left, q_right)
    cutting = cat["cutting"]
    # From the retrieval on, the cut-off sample travels with the gripper: keep it clear of the
    # grinder (before that it sits in the plate, the kerf, and so the cutter, beside it by design).
    carried = np.flatnonzero(cat["closed"] & (cat["stage"] >= STAGE_NAMES.index("retrieval")))
    sample_gaps = sample_box_gaps(geometry, layout, cfg, q_left[carried], tcp_right[carried]) if carried.size else np.zeros(0)
    # Deviation of the planned TCP (eq. 12 interpolation between solved points) from the ideal kerf line.
    gp = grinder_poses(layout, cfg)
    line = np.array([gp[k][:3, 3] for k in ("cut_start", "front_edge", "inner_corner", "side_edge")])
    dev = polyline_distance(tcp_left[cutting, :3, 3], line) if cutting.any() else np.zeros(0)
    axis_err = np.degrees(np.arccos(np.clip(tcp_left[cutting, 2, 2], -1.0, 1.0))) if cutting.any() else np.zeros(0)
    steps = {}
    for arm, q in (("left", q_left), ("right", q_right)):
        dq = np.abs(np.diff(q, axis=0))
        steps[arm] = {"max_dtheta_deg_per_sample": float(np.degrees(dq[:, 0::2].max())),
                      "max_dphi_deg_per_sample_bent": float(np.degrees(_bent_dphi(q, cfg.limits.phase_free_below)))}
    wp_err_p = max(float(np.max(w["position_error"])) for w in waypoints.values())
    wp_err_o = max(float(np.max(w["orientation_error"])) for w in waypoints.values())
    return {
        "duration_s": float(cat["t"][-1]),
        "samples": int(cat["t"].size),
        **_closest("arm", clearance, np.arange(clearance.size), cat),  # type: ignore[arg-type]
        **_closest("sample", sample_gaps, carried, cat),  # type: ignore[arg-type]
        "min_plate_clearance_left_m": float(plate_clearance(geometry, layout, q_left, "left").min()),
        "min_plate_clearance_right_m": float(plate_clearance(geometry, layout, q_right, "right").min()),
        "cut_path_max_deviation_m": float(dev.max()) if dev.size else 0.0,
        "cut_path_mean_deviation_m": float(dev.mean()) if dev.size else 0.0,
        "spindle_axis_max_error_deg": float(axis_err.max()) if axis_err.size else 0.0,
        "waypoint_position_error_max_m": wp_err_p,
        "waypoint_orientation_error_max_rad": wp_err_o,
        "waypoints": {k: int(len(v["q"])) for k, v in waypoints.items()},
        "step_limits": steps,
        "cut_duration_s": float(cutting.sum() / cfg.sample_rate_hz),
    }


def _bent_dphi(q: Array, free_below: float) -> float:
    th, ph = q[:, 0::2], q[:, 1::2]
    bent = (th[1:] >= free_below) & (th[:-1] >= free_below)
    d = np.abs(np.diff(ph, axis=0))
    return float(d[bent].max()) if bent.any() else 0.0


# ------------------------------------------------------------------------ outputs
def save_plan(plan: TaskPlan, path) -> None:
    """The plan's arrays as a compressed .npz (names as the TaskPlan fields)."""
    import io
    import json

    buf = io.BytesIO()
    np.savez_compressed(
        buf, t=plan.t, stage=plan.stage, segment=plan.segment, q_left=plan.q_left, q_right=plan.q_right,
        tcp_left=plan.tcp_left, tcp_right=plan.tcp_right, gripper_closed=plan.gripper_closed,
        spindle_on=plan.spindle_on, cutting=plan.cutting, stage_names=np.array(plan.stage_names),
        segment_names=np.array(plan.segment_names), metrics=np.array(json.dumps(plan.metrics)),
    )
    atomic_write_bytes(path, buf.getvalue())


def planar_demo_path(layout: TaskLayout, cfg: PlanConfig, n_points: int = 25) -> Array:
    """A straight cut in the grinder arm's own x-z plane (the setting of paper Fig. 10/11).

    Same height, spindle direction and distance range from the arm base as the task's
    kerf, but lying in the plane φ ∈ {0, π} can reach, so the free and planar phase modes
    can be compared on one path. World poses (n_points, 4, 4).
    """
    base = layout.left.base_transform()
    gp = grinder_poses(layout, cfg)
    pts = np.array([gp[k][:3, 3] for k in ("cut_start", "front_edge", "inner_corner", "side_edge")]) - base[:3, 3]
    r = np.hypot(pts[:, 0], pts[:, 1])
    poses = np.repeat(np.eye(4)[None], n_points, axis=0)
    poses[:, 0, 3] = base[0, 3] + np.linspace(r.min(), r.max(), n_points)
    poses[:, 1, 3] = base[1, 3]
    poses[:, 2, 3] = gp["cut_start"][2, 3]
    return poses


def solve_planar_demo(geometry: ArmGeometry, layout: TaskLayout, cfg: PlanConfig) -> dict:
    """The planar demo path solved in both phase modes from the same cold-started first point."""
    poses = planar_demo_path(layout, cfg)
    base = layout.left.base_transform()
    out = {}
    for phase in ("free", "planar"):
        first = solve_ik(geometry, poses[0], "axis", phase, tool="grinder", base=base, options=cfg.ik)
        if not first.success:
            raise UnreachableError("layout", f"planar demo path start: {first.message}")
        out[phase] = solve_path(geometry, poses, first.q, "axis", phase, tool="grinder", base=base,
                                options=cfg.ik, limits=cfg.limits)
    return out
