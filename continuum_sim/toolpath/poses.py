"""The task's toolpaths as world poses: key poses of the grinder and the gripper, densified into waypoints."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .. import kinematics as kin
from ..ik import interpolate_pose
from ..layout import TaskLayout
from .config import PlanConfig

Array = NDArray[np.float64]


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

    def pose(x: float, y: float) -> Array:
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


def densify(poses: list[Array], spacing: float, rotation_radius: float) -> Array:
    """Straight segments between the given poses, split so no step exceeds ``spacing``."""
    out = [poses[0]]
    for A, B in zip(poses[:-1], poses[1:]):
        d = pose_metric(A, B, rotation_radius)
        n = max(1, int(math.ceil(d / spacing - 1e-9)))
        out += [interpolate_pose(A, B, (i + 1) / n) for i in range(n)]
    return np.array(out)


def pose_metric(A: Array, B: Array, rotation_radius: float) -> float:
    rot = float(np.linalg.norm(kin.log_so3(A[:3, :3].T @ B[:3, :3])))
    return max(float(np.linalg.norm(B[:3, 3] - A[:3, 3])), rotation_radius * rot)
