"""Collision envelopes of the arms and their clearances: arm to arm, arm to plate, grinder arm to carried sample."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .. import kinematics as kin
from ..geometry import ArmGeometry
from ..layout import TaskLayout
from .config import PlanConfig

Array = NDArray[np.float64]


def disk_radii(geometry: ArmGeometry) -> Array:
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
    radii = [disk_radii(geometry)]
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
    radii = disk_radii(geometry)
    d = np.linalg.norm(np.maximum(np.maximum(lo - c, c - hi), 0.0), axis=-1) - radii
    return d.min(axis=-1)
