"""Planned clearance between the open gripper and the plate along the grasp approach.

The gripper's approach to its pre-grasp pose is a joint-space transfer (toolpath
`_joint_move`): its shape is planned, its sweep through space is not checked against the
plate. This measures it on the scene MuJoCo simulates: every plan sample of the clamping
stage before the jaws close is posed exactly (`set_arm_configuration`, jaws open), and
`mj_geomDistance` gives the signed distance between each collision geom of the gripper and
the plate's contact geoms (its two boxes and the sample). Negative = the plan drives the
gripper into the plate. Geometry only: the planned shape, not what the plant does with it.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..model.names import scoped
from ..model.options import model_geometry
from ..model.scene import PLATE_BODY, SAMPLE_BODY
from ..model.state import set_arm_configuration
from ..model.tools import GRIPPER
from ..toolpath import TaskPlan
from .config import ScenarioConfig

SEARCH_M = 0.05  # distances beyond this are reported as this (mj_geomDistance's distmax)


@dataclass(frozen=True)
class ApproachClearance:
    """Per plan sample of the clamping stage before closure: the smallest gripper–plate distance."""

    t: np.ndarray  # s, plan time
    segment: np.ndarray  # plan segment index (toolpath.SEGMENT_NAMES)
    distance_m: np.ndarray  # smallest signed distance over gripper geom × plate geom pairs
    pair: list[tuple[str, str]]  # the closest pair at each sample

    def min_over(self, segment_index: int | None = None) -> tuple[float, float, tuple[str, str]]:
        """(distance, time, pair) of the closest sample (of one segment, if given)."""
        sel = np.ones(len(self.t), bool) if segment_index is None else self.segment == segment_index
        idx = np.flatnonzero(sel)
        k = int(idx[np.argmin(self.distance_m[idx])])
        return float(self.distance_m[k]), float(self.t[k]), self.pair[k]


def gripper_approach_clearance(config: ScenarioConfig, plan: TaskPlan, model: mujoco.MjModel) -> ApproachClearance:
    """The planned gripper's clearance to the plate from the start of the clamping stage to the
    jaws' closing, on ``model`` (the scene of ``config``, e.g. `runner.build_scene_model`)."""
    arm = config.layout.arm_for(GRIPPER)
    prefix = scoped(arm, GRIPPER, "")  # the gripper's bodies after attachment
    data = mujoco.MjData(model)
    body_name = [model.body(b).name for b in range(model.nbody)]
    grip = [g for g in range(model.ngeom) if body_name[model.geom_bodyid[g]].startswith(prefix)
            and (model.geom_contype[g] or model.geom_conaffinity[g])]
    plate = [g for g in range(model.ngeom) if body_name[model.geom_bodyid[g]] in (PLATE_BODY, SAMPLE_BODY)
             and (model.geom_contype[g] or model.geom_conaffinity[g])]
    geometry = model_geometry(config.arm, config.model)
    idx = np.flatnonzero(plan.stage_mask("clamping") & ~plan.gripper_closed)
    q = plan.q(arm)
    dist, pairs = np.empty(len(idx)), []
    fromto = np.zeros(6)
    for n, i in enumerate(idx):
        set_arm_configuration(model, data, geometry, arm, q[i], config.model.joint)
        mujoco.mj_kinematics(model, data)
        best = (SEARCH_M, (model.geom(grip[0]).name, model.geom(plate[0]).name))
        for g1 in grip:
            for g2 in plate:
                d = mujoco.mj_geomDistance(model, data, g1, g2, SEARCH_M, fromto)
                if d < best[0]:
                    best = (d, (model.geom(g1).name, model.geom(g2).name))
        dist[n] = best[0]
        pairs.append(best[1])
    return ApproachClearance(plan.t[idx], plan.segment[idx], dist, pairs)
