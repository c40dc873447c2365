"""``plan_task``: the timed dual-arm plan of the sample-removal task, stage by stage (SPEC §5)."""

from __future__ import annotations

from tqdm import tqdm

from ..geometry import ArmGeometry
from ..layout import TaskLayout
from ..workspace import UnreachableError, check_poses
from .config import PlanConfig
from .moves import ArmPlanner, Move, dwell, joint_move
from .poses import grinder_poses, gripper_poses
from .sampling import sample_plan
from .task_plan import STAGE_NAMES, TaskPlan


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

    grinder = ArmPlanner(geometry, layout, cfg, "left", "axis", cfg.grinder_phase)
    gripper = ArmPlanner(geometry, layout, cfg, "right", "full", cfg.gripper_phase)
    qL0, qR0 = cfg.q_initial("left"), cfg.q_initial("right")
    S = {name: i for i, name in enumerate(STAGE_NAMES)}
    timeline: list[tuple[int, list[Move]]] = []  # (stage, moves of the active arm)

    steps = tqdm(total=5, desc="planning", disable=not cfg.progress)
    # 1 initial
    timeline.append((S["initial"], [dwell("left", S["initial"], "hold", qL0, cfg.dwell_initial)]))
    steps.update()
    # 2 clamping: joint transfer to the pre-grasp shape, Cartesian grasp, close.
    q_pre = gripper.nearest_solution(hp["pre_grasp"], qR0)
    m_app = joint_move("right", S["clamping"], "approach", qR0, q_pre, cfg, gripper.phase)
    m_grasp = gripper.path_move(S["clamping"], "grasp", [hp["pre_grasp"], hp["grasp"]], q_pre, cfg.fast_speed / 2)
    m_close = dwell("right", S["clamping"], "close", m_grasp.q_end, cfg.dwell_close, gripper_closed=True)
    timeline.append((S["clamping"], [m_app, m_grasp, m_close]))
    steps.update()
    # 3 milling: joint transfer to the pre-cut shape, then horizontal moves at the cutting height.
    q_cut = grinder.nearest_solution(gp["pre_cut"], qL0)
    spin = dict(spindle_on=True)
    kerf = [gp[k] for k in ("cut_start", "front_edge", "inner_corner", "side_edge")]
    m_spin = dwell("left", S["milling"], "spin_up", qL0, cfg.dwell_spin_up, **spin)
    m_tr = joint_move("left", S["milling"], "approach", qL0, q_cut, cfg, grinder.phase, **spin)
    m_app = grinder.path_move(S["milling"], "approach", [gp["pre_cut"], gp["cut_start"]], q_cut, cfg.fast_speed, **spin)
    m_settle = dwell("left", S["milling"], "approach", m_app.q_end, cfg.dwell_before_cut, **spin)
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
    m_back = joint_move("left", S["return"], "return", m_ret.q_end, qL0, cfg, grinder.phase)
    m_final = dwell("left", S["return"], "final", qL0, cfg.dwell_final)
    timeline.append((S["return"], [m_ret, m_back, m_final]))
    steps.update()
    steps.close()

    plan = sample_plan(geometry, layout, cfg, timeline, qL0, qR0, {**grinder.waypoints, **gripper.waypoints})
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
