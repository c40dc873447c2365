"""The in-plane demo path (paper Fig. 10/11), solved in the free and the planar phase mode."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..geometry import ArmGeometry
from ..ik import solve_ik, solve_path
from ..layout import TaskLayout
from ..workspace import UnreachableError
from .config import PlanConfig
from .poses import grinder_poses

Array = NDArray[np.float64]


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
