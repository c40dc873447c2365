"""Map between PCC configurations q and the generated model's joint coordinates."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..geometry import ArmGeometry
from ..kinematics import to_bending


def segment_rotation_vectors(geometry: ArmGeometry, q: ArrayLike) -> np.ndarray:
    """(n_joints, 3) rotation vector of every joint of the uniformly bent sections."""
    w = to_bending(np.asarray(q, dtype=float))
    out = []
    for k, section in enumerate(geometry.sections):
        u, v = w[2 * k], w[2 * k + 1]
        out.extend([np.array([-v, u, 0.0]) / section.n_segments] * section.n_segments)
    return np.array(out)


def ball_quaternions(geometry: ArmGeometry, q: ArrayLike) -> np.ndarray:
    """(n_joints, 4) MuJoCo (w, x, y, z) quaternions of the ball joints at configuration q."""
    rv = segment_rotation_vectors(geometry, q)
    angle = np.linalg.norm(rv, axis=1)
    half = angle / 2.0
    scale = 0.5 * np.sinc(half / np.pi)  # sin(angle/2)/angle
    return np.column_stack([np.cos(half), rv * scale[:, None]])


def hinge_pair_angles(geometry: ArmGeometry, q: ArrayLike) -> np.ndarray:
    """(n_joints, 2) angles (a about x, b about y) pointing each disk's z like the PCC model.

    Joint i (1-based) composes Rx(a)·Ry(b) for odd i and Ry(b)·Rx(a) for even i (the
    builder alternates the order so the universal joints' second-order twist cancels in
    pairs); either way the disk axis points exactly where the PCC model points it.
    """
    rv = segment_rotation_vectors(geometry, q)
    beta = np.linalg.norm(rv, axis=1)
    axis_dir = np.where(beta[:, None] > 0, rv / np.where(beta > 0, beta, 1.0)[:, None], 0.0)
    # rotation about (-sin φ, cos φ, 0) by β sends e_z to (sin β cos φ, sin β sin φ, cos β)
    cos_phi, sin_phi = axis_dir[:, 1], -axis_dir[:, 0]
    ex, ey, ez = np.sin(beta) * cos_phi, np.sin(beta) * sin_phi, np.cos(beta)
    xy = (np.arange(1, len(rv) + 1) % 2) == 1
    # Rx(a)Ry(b) e_z = (sin b, -sin a cos b, cos a cos b); Ry(b)Rx(a) e_z = (sin b cos a, -sin a, cos a cos b)
    a = np.where(xy, np.arctan2(-ey, ez), np.arcsin(np.clip(-ey, -1.0, 1.0)))
    b = np.where(xy, np.arcsin(np.clip(ex, -1.0, 1.0)), np.arctan2(ex, ez))
    return np.column_stack([a, b])


def hinge_triple_angles(geometry: ArmGeometry, q: ArrayLike) -> np.ndarray:
    """(n_joints, 3) angles (a, b, c) with Rx(a)·Ry(b)·Rz(c) equal to each PCC joint rotation.

    The twist hinge makes the XYZ Euler decomposition exact: c ≈ −ab/2 is the
    second-order twist a universal pair would otherwise add.
    """
    rv = segment_rotation_vectors(geometry, q)
    out = np.zeros((len(rv), 3))
    for i, w in enumerate(rv):
        angle = float(np.linalg.norm(w))
        if angle == 0.0:
            continue
        k = w / angle
        kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        r = np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * kx @ kx
        out[i] = (np.arctan2(-r[1, 2], r[2, 2]), np.arcsin(np.clip(r[0, 2], -1.0, 1.0)), np.arctan2(-r[0, 1], r[0, 0]))
    return out


def arm_qpos_addresses(model, arm: str, n_joints: int, joint: str) -> np.ndarray:
    """qpos addresses of an arm's joints, in disk order (ball: 4 each, hinge_pair: 2, hinge_triple: 3)."""
    import mujoco

    addresses: list[int] = []
    for i in range(1, n_joints + 1):
        if joint == "ball":
            jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{arm}/joint_{i}")
            addresses.extend(range(model.jnt_qposadr[jid], model.jnt_qposadr[jid] + 4))
        else:
            for suffix in ("x", "y", "z") if joint == "hinge_triple" else ("x", "y"):
                jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{arm}/joint_{i}_{suffix}")
                addresses.append(model.jnt_qposadr[jid])
        if min(addresses[-2:]) < 0:
            raise KeyError(f"joint {arm}/joint_{i} not found")
    return np.array(addresses)


def set_arm_configuration(model, data, model_geometry: ArmGeometry, arm: str, q: ArrayLike, joint: str = "ball") -> None:
    """Write the PCC configuration q of ``arm`` into ``data.qpos`` (call mj_forward after)."""
    n = sum(s.n_segments for s in model_geometry.sections)
    addresses = arm_qpos_addresses(model, arm, n, joint)
    if joint == "ball":
        values = ball_quaternions(model_geometry, q)
    elif joint == "hinge_triple":
        values = hinge_triple_angles(model_geometry, q)
    else:
        values = hinge_pair_angles(model_geometry, q)
    data.qpos[addresses] = values.ravel()
