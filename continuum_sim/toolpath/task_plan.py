"""``TaskPlan``, the timed plan both arms follow, its stage and segment names, and its .npz file."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..configio import atomic_write_bytes

Array = NDArray[np.float64]

STAGE_NAMES = ("initial", "clamping", "milling", "retrieval", "return")
SEGMENT_NAMES = ("hold", "approach", "grasp", "close", "spin_up", "cutting", "exit", "return", "carry", "final")


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
