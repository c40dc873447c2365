"""Cable tensions that hold an arm pose quasi-statically (motor sizing).

At a PCC pose the joint springs push back with ``qfrc_spring``; the cables balance it
through their tendon Jacobians, Jᵀ·T = −qfrc_spring with T ≥ 0 (non-negative least
squares over the cables of the most distal bent section and of every section proximal to
it: those must cancel the moments of the distal cables passing through them). Equal
tension in the three cables of a straight section (120° apart) adds no moment there, so
that free common mode is dropped: the result is the least pull that holds the pose.
Gravity and pre-tension are not included. Use ball joints (``model.joint = "ball"``):
they represent the PCC pose exactly, while hinge pairs leave a second-order residual that
least squares would trade for large common-mode tensions.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import nnls

from ..geometry import ArmGeometry
from . import names
from .state import set_arm_configuration


def tendon_jacobian(model, data) -> np.ndarray:
    """∂(tendon length)/∂(generalised position) at ``data.qpos``, central differences (``ten_J`` is stored sparse)."""
    import mujoco

    qpos = data.qpos.copy()
    jac = np.zeros((model.ntendon, model.nv))
    step = 1e-6
    for i in range(model.nv):
        lengths = []
        for sign in (1.0, -1.0):
            dq = np.zeros(model.nv)
            dq[i] = sign * step
            data.qpos[:] = qpos
            mujoco.mj_integratePos(model, data.qpos, dq, 1.0)
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            mujoco.mj_tendon(model, data)
            lengths.append(data.ten_length.copy())
        jac[:, i] = (lengths[0] - lengths[1]) / (2.0 * step)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    return jac


def holding_tensions(model, geometry: ArmGeometry, q: np.ndarray, joint: str, arm: str = names.SINGLE_ARM) -> tuple[np.ndarray, float, float]:
    """(tensions of the cables of sections 0..k (N), residual (N·m), |spring force| (N·m)) holding pose ``q``.

    ``model``: a single-arm model of ``geometry`` (tendons on; its tendons in cable order).
    """
    import mujoco

    data = mujoco.MjData(model)
    set_arm_configuration(model, data, geometry, arm, q, joint)
    mujoco.mj_forward(model, data)
    bent = [k for k in range(geometry.n_sections) if q[2 * k] != 0.0]
    last = max(bent) if bent else 0
    cables = np.arange(3 * (last + 1))
    spring = data.qfrc_spring.copy()
    jac = tendon_jacobian(model, data)[cables]
    # a tendon of tension T adds −T·∂length/∂q to the generalised force
    tension, residual = nnls(-jac.T, -spring)
    for k in range(last):
        if q[2 * k] == 0.0:
            tension[3 * k : 3 * k + 3] -= tension[3 * k : 3 * k + 3].min()
    return tension, float(residual), float(np.linalg.norm(spring))
