"""The stages' moves laid end to end and sampled at the plan rate into a ``TaskPlan``."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .. import kinematics as kin
from ..configio import ConfigError
from ..geometry import ArmGeometry
from ..layout import TaskLayout
from .config import PlanConfig
from .moves import Move
from .plan_metrics import plan_metrics
from .task_plan import SEGMENT_NAMES, TaskPlan

Array = NDArray[np.float64]


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


def sample_plan(geometry: ArmGeometry, layout: TaskLayout, cfg: PlanConfig, timeline: list[tuple[int, list[Move]]],
                qL0: Array, qR0: Array, waypoints: dict[str, dict]) -> TaskPlan:
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
    metrics = plan_metrics(geometry, layout, cfg, cat, q_left, q_right, tcp_left, tcp_right, waypoints)
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
