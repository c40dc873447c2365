"""The capstan relation T_out = T_in·e^(−μθ) as a validation check of the cable-friction model.

The rig: the scenario's arm (hinge pairs, 4 ms, no gravity), one proximal cable driven by a
pure tension source at the motor (force = control), reeled in monotonically until the
section is bent ~90° and held until it is at rest. The anchor tension is read from the
model's statics, not from the friction code: the flexure spring torque at the section's
last joint over the cable's moment arm there (MuJoCo's tendon Jacobian). Its ratio to the
motor tension is compared with e^(−μθ), θ the cable's total direction change (its wrap).

Used by ``continuum-sim validate`` (rows ``capstan``) and ``benchmarks/friction.py``.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def rig() -> tuple[Any, int, int]:
    """(model, actuator, tendon): the arm with its proximal cable 0 driven by a pure tension source."""
    import mujoco

    from ..geometry import ArmGeometry
    from ..model import names
    from ..model.arm import build_single_arm_model
    from ..model.options import ModelOptions

    root = build_single_arm_model(ArmGeometry.default(), ModelOptions(joint="hinge_pair", timestep=0.004), gravity=False)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    cable = names.scoped(names.SINGLE_ARM, names.cable(0, 0))  # the proximal section's first cable
    act = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, cable)
    ten = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, cable)
    model.actuator_gainprm[act, :] = 0.0
    model.actuator_gainprm[act, 0] = 1.0  # force = ctrl: a known motor tension
    model.actuator_biasprm[act, :] = 0.0
    model.actuator_ctrlrange[act] = (-1000.0, 0.0)
    model.actuator_forcerange[act] = (-1000.0, 0.0)
    return model, act, ten


def tension_for_bend(model: Any, ten: int, bend: float) -> float:
    """Frictionless statics estimate of the motor tension bending the section by ``bend`` (rad).

    Each of the n joints turns bend/n against its flexure spring k, the cable on the hole
    radius r: T ≈ k·(bend/n)/r. A starting point only; the results are measured.
    """
    adr, num = model.tendon_adr[ten], model.tendon_num[ten]
    first_disk = model.site_bodyid[model.wrap_objid[adr + 1]]
    j = model.body_jntadr[first_disk]
    k = float(np.max(model.jnt_stiffness[j : j + model.body_jntnum[first_disk]]))
    r = float(np.linalg.norm(model.site_pos[model.wrap_objid[adr]][:2]))
    return k * (bend / (num - 1)) / r


def hold(model: Any, data: Any, act: int, start: float, end: float, ramp: int, steps: int) -> None:
    """Ramp the motor tension from ``start`` to ``end`` over ``ramp`` steps, then hold ``steps``."""
    import mujoco

    for T in np.r_[np.linspace(start, end, ramp), np.full(steps, end)]:
        data.ctrl[act] = -T
        mujoco.mj_step(model, data)


def settle(model: Any, data: Any, act: int, T: float, max_steps: int = 5000) -> None:
    """Hold the motor tension until the arm is at rest (|qvel| < 1e-4 rad/s)."""
    for _ in range(max_steps // 250):
        hold(model, data, act, T, T, 0, 250)
        if np.abs(data.qvel).max() < 1e-4:
            return


def anchor_tension(model: Any, data: Any, ten: int) -> float:
    """Cable tension at its anchor from the statics: spring torque at the last joint / moment arm."""
    import mujoco

    adr, num = model.tendon_adr[ten], model.tendon_num[ten]
    body = model.site_bodyid[model.wrap_objid[adr + num - 1]]
    first = model.jnt_dofadr[model.body_jntadr[body]]
    dofs = np.arange(first, first + model.body_jntnum[body])
    J = np.zeros((model.ntendon, model.nv))
    mujoco.mju_sparse2dense(J, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind)
    g = J[ten, dofs]
    return float(data.qfrc_spring[dofs] @ g / (g @ g))


def wrap_angle(model: Any, data: Any, ten: int) -> float:
    """The cable's total direction change (rad): base z to its last piece (planar, monotonic bend)."""
    adr, num = model.tendon_adr[ten], model.tendon_num[ten]
    p = data.site_xpos[model.wrap_objid[adr : adr + num]]
    last = (p[-1] - p[-2]) / np.linalg.norm(p[-1] - p[-2])
    return float(np.arccos(np.clip(last[2], -1.0, 1.0)))


def measure(mu: float, target_deg: float = 90.0, model_rig: tuple[Any, int, int] | None = None) -> dict[str, float]:
    """Load the rig to ~``target_deg`` with friction ``mu`` and measure the anchor/motor ratio."""
    import mujoco

    from ..model.friction_options import CableFrictionConfig
    from ..plant.friction import install_cable_friction

    model, act, ten = rig() if model_rig is None else model_rig
    target = np.radians(target_deg)
    T = tension_for_bend(model, ten, target)
    wrap, ratio, qvel = float("nan"), float("nan"), float("nan")
    for _ in range(5):
        data = mujoco.MjData(model)
        data.ctrl[:] = model.actuator_ctrlrange[:, 1]
        handle = install_cable_friction(model, data, CableFrictionConfig(mu=mu))
        try:
            hold(model, data, act, 0.0, T, 250, 0)  # monotonic loading: the cable only reels in
            settle(model, data, act, T)
            mujoco.mj_forward(model, data)
            handle.check()
        finally:
            handle.uninstall()
        wrap = wrap_angle(model, data, ten)
        ratio = anchor_tension(model, data, ten) / T
        qvel = float(np.abs(data.qvel).max())
        if abs(wrap - target) < np.radians(0.5):
            break
        T *= target / wrap
    return {"mu": mu, "motor_tension_n": T, "wrap_rad": wrap, "anchor_over_motor": ratio, "max_qvel": qvel,
            "capstan": float(np.exp(-mu * wrap))}


def validation_checks() -> list[Any]:
    """The capstan rows of ``continuum-sim validate``: μ 0.15 in --quick, 0.1/0.15/0.2 in the full run."""
    from .report import Check, row

    reference = "capstan relation T_anchor/T_motor = e^(−μθ) (cable friction)"

    def run(quick: bool) -> list[Any]:
        shared = rig()
        rows = []
        for mu in (0.15,) if quick else (0.1, 0.15, 0.2):
            m = measure(mu, model_rig=shared)
            error = 100.0 * (m["anchor_over_motor"] / m["capstan"] - 1.0)
            rows.append(row("capstan", reference, f"anchor/motor tension vs e^(−μθ), μ {mu:g}, θ {np.degrees(m['wrap_rad']):.1f}°",
                            error, 5.0, "%", ".2f"))
        return rows

    return [Check("capstan", reference, run)]
