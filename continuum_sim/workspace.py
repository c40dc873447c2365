"""Cooperative workspace of the two arms (SPEC §4, paper §3.2 and Fig. 4).

Each arm's reachable tool points are sampled over θ ∈ [0, θmax], φ ∈ [0, 2π) per section
(seeded, so the same config gives the same cloud) and binned into voxels; the overlap of
the two voxel sets is where both tools can be, i.e. where collaborative work happens.
The voxel sets answer "is this position inside the sampled workspace?" quickly; whether
a *pose* (position and orientation) is reachable is the IK's call (``check_poses``), and
the planner refuses a plan whose first unreachable pose it names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import kinematics as kin
from .configio import ConfigError, atomic_write_figure, require_int, require_range
from .geometry import ArmGeometry
from .ik import solve_ik
from .layout import TaskLayout

Array = NDArray[np.float64]


@dataclass(frozen=True)
class WorkspaceConfig:
    """How the workspace is sampled and binned."""

    samples: int = 200_000  # configurations per arm
    seed: int = 0
    voxel: float = 0.01  # m, edge of the occupancy voxels
    point: Literal["tcp", "tip"] = "tcp"  # the tool centre point or the last disk centre
    section_half_width: float = 0.01  # m: points with |y - y0| below this form the section view

    def __post_init__(self) -> None:
        require_int("samples", self.samples, 100, 20_000_000)
        require_int("seed", self.seed, 0)
        require_range("voxel", self.voxel, 0.001, 0.2, low_inclusive=True)
        if self.point not in ("tcp", "tip"):
            raise ConfigError("point", f"must be 'tcp' or 'tip' (got {self.point!r})")
        require_range("section_half_width", self.section_half_width, 0.0, 0.5)


def sample_configurations(geometry: ArmGeometry, n: int, seed: int) -> Array:
    """(n, 2S) configurations, θ uniform in [0, θmax] and φ uniform in [0, 2π) (paper Fig. 4)."""
    rng = np.random.default_rng(seed)
    q = np.empty((n, 2 * geometry.n_sections))
    q[:, 0::2] = rng.uniform(0.0, 1.0, (n, geometry.n_sections)) * geometry.max_bend
    q[:, 1::2] = rng.uniform(0.0, 2.0 * np.pi, (n, geometry.n_sections))
    return q


def arm_cloud(geometry: ArmGeometry, base: ArrayLike, tool_length: float, n: int, seed: int,
              chunk: int = 20_000, progress: bool = False, label: str = "workspace") -> Array:
    """(n, 3) world positions of the tool point over sampled configurations."""
    from tqdm import tqdm

    q = sample_configurations(geometry, n, seed)
    out = np.empty((n, 3))
    for start in tqdm(range(0, n, chunk), desc=label, disable=not progress):
        w = kin.to_bending(q[start : start + chunk])
        T = kin.forward_kinematics_bending(geometry, w, base, tool_length)
        out[start : start + chunk] = T[:, :3, 3]
    return out


@dataclass(frozen=True)
class VoxelSet:
    """Occupied voxels of a point cloud: integer keys ``floor(p / voxel)``."""

    voxel: float
    keys: frozenset

    @classmethod
    def from_points(cls, points: Array, voxel: float) -> VoxelSet:
        idx = np.floor(np.asarray(points) / voxel).astype(np.int64)
        return cls(voxel, frozenset(map(tuple, np.unique(idx, axis=0).tolist())))

    @property
    def volume(self) -> float:
        return len(self.keys) * self.voxel**3

    def contains(self, points: ArrayLike, dilate: int = 0) -> NDArray[np.bool_]:
        """Whether each point's voxel (or, with ``dilate``, a voxel that near) is occupied."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        idx = np.floor(p / self.voxel).astype(np.int64)
        offsets = [(i, j, k) for i in range(-dilate, dilate + 1) for j in range(-dilate, dilate + 1)
                   for k in range(-dilate, dilate + 1)]
        keys = self.keys
        return np.array([any((a + i, b + j, c + k) in keys for i, j, k in offsets) for a, b, c in idx.tolist()])

    def __and__(self, other: VoxelSet) -> VoxelSet:
        if not math.isclose(self.voxel, other.voxel):
            raise ValueError("voxel sizes differ")
        return VoxelSet(self.voxel, self.keys & other.keys)

    def centres(self) -> Array:
        if not self.keys:
            return np.zeros((0, 3))
        return (np.array(sorted(self.keys), dtype=float) + 0.5) * self.voxel


@dataclass(frozen=True)
class CooperativeWorkspace:
    """Both arms' sampled tool-point clouds, their voxel sets and the overlap."""

    left_points: Array
    right_points: Array
    left: VoxelSet
    right: VoxelSet
    overlap: VoxelSet
    config: WorkspaceConfig

    def arm(self, name: str) -> VoxelSet:
        if name == "left":
            return self.left
        if name == "right":
            return self.right
        raise ValueError(f"arm: must be 'left' or 'right' (got {name!r})")

    def summary(self) -> dict:
        return {
            "samples_per_arm": self.config.samples,
            "voxel_m": self.config.voxel,
            "point": self.config.point,
            "left_volume_m3": round(self.left.volume, 6),
            "right_volume_m3": round(self.right.volume, 6),
            "overlap_volume_m3": round(self.overlap.volume, 6),
            "overlap_z_range_m": _z_range(self.overlap),
        }


def _z_range(voxels: VoxelSet) -> list[float] | None:
    c = voxels.centres()
    if not len(c):
        return None
    return [round(float(c[:, 2].min()), 4), round(float(c[:, 2].max()), 4)]


def compute_workspace(geometry: ArmGeometry, layout: TaskLayout, config: WorkspaceConfig | None = None,
                      progress: bool = False) -> CooperativeWorkspace:
    """Sample both arms (left: grinder, right: gripper) in the world frame."""
    config = config or WorkspaceConfig()
    clouds = {}
    for offset, name in enumerate(("left", "right")):
        mount = layout.mount(name)
        length = geometry.tools.length(mount.tool) if config.point == "tcp" else 0.0
        clouds[name] = arm_cloud(geometry, mount.base_transform(), length, config.samples, config.seed + offset,
                                 progress=progress, label=f"{name} arm")
    left = VoxelSet.from_points(clouds["left"], config.voxel)
    right = VoxelSet.from_points(clouds["right"], config.voxel)
    return CooperativeWorkspace(clouds["left"], clouds["right"], left, right, left & right, config)


def plot_workspace(ws: CooperativeWorkspace, path: str | Path, layout: TaskLayout | None = None,
                   task_points: dict[str, Array] | None = None, section_y: float = 0.0) -> None:
    """Paper Fig. 4: (a) both clouds in 3D, (b) section view at y = ``section_y`` with the overlap."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(13, 6))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    rng = np.random.default_rng(0)
    for pts, colour, name in ((ws.left_points, "tab:blue", "left (grinder)"), (ws.right_points, "tab:red", "right (gripper)")):
        sub = pts[rng.choice(len(pts), min(len(pts), 6000), replace=False)]
        ax3.scatter(*(1000 * sub.T), s=1, alpha=0.25, color=colour, label=name)
    ov = ws.overlap.centres()
    if len(ov):
        sub = ov[rng.choice(len(ov), min(len(ov), 4000), replace=False)]
        ax3.scatter(*(1000 * sub.T), s=2, alpha=0.5, color="gold", label="overlap")
    ax3.set_xlabel("x [mm]")
    ax3.set_ylabel("y [mm]")
    ax3.set_zlabel("z [mm]")
    ax3.set_title(f"(a) {ws.config.point.upper()} workspaces")
    ax3.legend(loc="upper left", fontsize=8, markerscale=6)

    ax = fig.add_subplot(1, 2, 2)
    half = ws.config.section_half_width
    for pts, colour, name in ((ws.left_points, "tab:blue", "left"), (ws.right_points, "tab:red", "right")):
        sel = pts[np.abs(pts[:, 1] - section_y) < half]
        ax.scatter(1000 * sel[:, 0], 1000 * sel[:, 2], s=1, alpha=0.3, color=colour, label=f"{name} arm")
    if len(ov):
        v = ws.config.voxel
        sel = ov[np.abs(ov[:, 1] - section_y) < max(half, v / 2)]
        ax.scatter(1000 * sel[:, 0], 1000 * sel[:, 2], s=6, marker="s", color="gold", alpha=0.8, label="overlap")
    if layout is not None:
        plate = layout.plate
        x0, x1 = plate.corner_x - plate.size[0], plate.corner_x
        ax.fill_between([1000 * x0, 1000 * x1], 1000 * (plate.top_z - plate.thickness), 1000 * plate.top_z,
                        color="0.4", alpha=0.6, label="plate (x extent)")
        for name in ("left", "right"):
            p = layout.mount(name).position
            ax.plot(1000 * p[0], 1000 * p[2], "k^", ms=8)
    if task_points:
        for label, pts in task_points.items():
            pts = np.atleast_2d(pts)
            ax.plot(1000 * pts[:, 0], 1000 * pts[:, 2], ".-", lw=1, ms=3, label=label)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("z [mm]")
    ax.set_title(f"(b) section view |y - {1000 * section_y:.0f} mm| < {1000 * half:.0f} mm")
    ax.legend(loc="lower center", fontsize=8, markerscale=4, ncol=2)
    atomic_write_figure(fig, path)


class UnreachableError(ConfigError):
    """A planned pose lies outside an arm's workspace; the message names the first one."""


def check_poses(geometry: ArmGeometry, layout: TaskLayout, arm: str, poses: list[tuple[str, Array]],
                orientation: str, phase: str = "free", options=None, workspace: CooperativeWorkspace | None = None):
    """Solve every named world pose cold; raise ``UnreachableError`` at the first that fails.

    Returns the IK results in order. With a sampled ``workspace`` the message also says
    whether the position alone is outside the sampled tool-point cloud.
    """
    mount = layout.mount(arm)
    results = []
    for name, pose in poses:
        res = solve_ik(geometry, pose, orientation, phase, tool=mount.tool, base=mount.base_transform(), options=options)  # type: ignore[arg-type]
        if not res.success:
            p = 1000 * np.asarray(pose)[:3, 3]
            hint = ""
            if workspace is not None:
                inside = bool(workspace.arm(arm).contains(np.asarray(pose)[:3, 3], dilate=1)[0])
                hint = " (position inside the sampled workspace: the orientation is what cannot be reached)" if inside \
                    else " (position outside the sampled workspace)"
            raise UnreachableError(
                "layout",
                f"{name} at ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm is outside the {arm} arm's workspace for its "
                f"{mount.tool} in '{orientation}' orientation mode: position error {1000 * res.position_error:.2f} mm, "
                f"orientation error {np.degrees(res.orientation_error):.2f} deg{hint}; move the plate "
                f"(layout.plate.corner_x/corner_y/top_z) or the grasp (layout.grasp)",
            )
        results.append(res)
    return results
