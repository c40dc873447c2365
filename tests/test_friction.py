"""Cable friction in the holes (continuum_sim.plant.friction, issue 13).

References are independent of the friction kernel: MuJoCo's own spatial-tendon lengths
and Jacobians for the cable kernel; for the capstan, the tension at the anchor is read
from the model's statics (the flexure spring torque at the last joint over MuJoCo's
tendon moment arm there) and the wrap from the simulated hole positions, against the
textbook T_out = T_in·e^(−μθ).
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from continuum_sim.configio import ConfigError
from continuum_sim.geometry import ArmGeometry
from continuum_sim.model import friction_options as fo
from continuum_sim.model.arm import build_single_arm_model
from continuum_sim.model.options import ModelOptions
from continuum_sim.plant import friction as fr
from continuum_sim.plant.cable_routing import CablePieces, cable_routing
from continuum_sim.validation import capstan

CABLE = "arm/cable_0_0"  # proximal section, hole at 0°: pulling it bends the section toward +x


def _compile(options: ModelOptions) -> mujoco.MjModel:
    geometry = ArmGeometry.default()
    if options.joint == "hinge_triple":  # a twist spring needs the central ball joint
        geometry = dataclasses.replace(geometry, central_joint="ball")
    root = build_single_arm_model(geometry, options, gravity=False)
    return mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())


@pytest.fixture(scope="module")
def rig() -> tuple[mujoco.MjModel, int, int]:
    """The scenario's arm (hinge pairs, 4 ms), no gravity; cable_0_0 driven by a pure force motor
    (the capstan check's own rig, continuum_sim.validation.capstan)."""
    return capstan.rig()



def _slack(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    data.ctrl[:] = model.actuator_ctrlrange[
        :, 1
    ]  # every position-driven cable paid out: no tension


def _drive(model, data, act: int, tensions: np.ndarray, ten: int, record: bool = False):
    """Step through motor tensions (one per step); returns (tension, section bend) per step."""
    out = []
    for T in tensions:
        data.ctrl[act] = -T
        mujoco.mj_step(model, data)
        if record:
            out.append((T, _section_bend(model, data, ten)))
    return np.array(out)


def _settle(model, data, act: int, T: float, ten: int, max_steps: int = 3000) -> None:
    """Hold the motor tension until the arm is at rest (|qvel| < 1e-4 rad/s) or max_steps."""
    for _ in range(max_steps // 250):
        _drive(model, data, act, np.full(250, T), ten)
        if np.abs(data.qvel).max() < 1e-4:
            return


def _hole_points(model, data, ten: int) -> np.ndarray:
    adr, num = model.tendon_adr[ten], model.tendon_num[ten]
    return data.site_xpos[model.wrap_objid[adr : adr + num]]


def _section_bend(model, data, ten: int) -> float:
    """Angle (rad) between the base z and the last disk's z of the cable's section."""
    adr, num = model.tendon_adr[ten], model.tendon_num[ten]
    body = model.site_bodyid[model.wrap_objid[adr + num - 1]]
    return float(np.arccos(np.clip(data.xmat[body].reshape(3, 3)[2, 2], -1.0, 1.0)))



def test_config_validates_itself() -> None:
    with pytest.raises(ConfigError, match="^mu: "):
        fo.CableFrictionConfig(mu=-0.1)
    with pytest.raises(ConfigError, match="^presliding: "):
        fo.CableFrictionConfig(presliding=0.0)
    assert fo.CableFrictionConfig().mu == fo.DEFAULT_MU


# ------------------------------------------------------------------------- cable kernel
@pytest.mark.parametrize("joint", ["hinge_pair", "ball", "hinge_triple"])
def test_cable_kernel_matches_mujoco_tendons(joint: str) -> None:
    """Piece lengths summed and local gradients scattered = MuJoCo's ten_length and ten_J (the oracle), 1e-12."""
    model = _compile(ModelOptions(joint=joint, tendons=True))
    data = mujoco.MjData(model)
    kernel = CablePieces(cable_routing(model))
    assert kernel.routing.n_pieces == 3 * (10 + 20 + 30)
    rng = np.random.default_rng(3)
    for _ in range(2):
        for j in range(model.njnt):
            a = model.jnt_qposadr[j]
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
                rv = rng.normal(size=3) * 0.12
                mujoco.mju_axisAngle2Quat(
                    data.qpos[a : a + 4], rv / np.linalg.norm(rv), np.linalg.norm(rv)
                )
            else:
                data.qpos[a] = rng.normal() * 0.12
        mujoco.mj_forward(model, data)
        kernel.evaluate(data)
        ids = kernel.routing.tendon_ids
        J = np.zeros((model.ntendon, model.nv))
        mujoco.mju_sparse2dense(
            J, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind
        )
        np.testing.assert_allclose(
            kernel.cable_lengths(), data.ten_length[ids], rtol=0, atol=1e-12
        )
        np.testing.assert_allclose(
            kernel.cable_jacobian(model.nv), J[ids], rtol=0, atol=1e-12
        )


# ------------------------------------------------------------------------------ capstan
@pytest.mark.parametrize("mu", [0.1, 0.2])
def test_capstan_over_90_degrees(rig, mu: float) -> None:
    """Section held bent ~90° by a motor tension: T_anchor/T_motor = e^(−μθ) within 5 %."""
    model, act, ten = rig
    target_wrap = np.pi / 2
    T = capstan.tension_for_bend(
        model, ten, target_wrap
    )  # then scaled by the measured wrap until ~90°
    for _attempt in range(4):
        data = mujoco.MjData(model)
        _slack(model, data)
        handle = fr.install_cable_friction(model, data, fo.CableFrictionConfig(mu=mu))
        # monotonic loading (the cable only reels in), then hold until static
        _drive(model, data, act, np.linspace(0.0, T, 250), ten)
        _settle(model, data, act, T, ten)
        mujoco.mj_forward(model, data)
        p = _hole_points(model, data, ten)
        last = (p[-1] - p[-2]) / np.linalg.norm(p[-1] - p[-2])
        wrap = float(
            np.arccos(last[2])
        )  # base z (the cable's entry) to its last piece: planar, monotonic
        if abs(wrap - target_wrap) < np.radians(2.0):
            break
        T *= target_wrap / wrap
    assert abs(np.degrees(wrap) - 90.0) < 2.0
    assert np.abs(data.qvel).max() < 1e-3  # static
    ratio = capstan.anchor_tension(model, data, ten) / T
    expected = np.exp(-mu * wrap)
    assert ratio == pytest.approx(expected, rel=0.05)
    assert ratio == pytest.approx(np.exp(-mu * np.pi / 2), rel=0.05)
    # the handle's own bookkeeping agrees with the statics
    c = list(handle.routing.names).index(CABLE)
    assert handle.anchor_ratio()[c] == pytest.approx(ratio, rel=0.01)
    handle.uninstall()


def test_frictionless_anchor_carries_the_motor_tension(rig) -> None:
    """μ = 0: the same statics give T_anchor = T_motor (the measurement itself is sound)."""
    model, act, ten = rig
    data = mujoco.MjData(model)
    _slack(model, data)
    handle = fr.install_cable_friction(model, data, fo.CableFrictionConfig(mu=0.0))
    assert not handle.active
    T = capstan.tension_for_bend(model, ten, np.pi / 2)
    _drive(model, data, act, np.linspace(0.0, T, 250), ten)
    _settle(model, data, act, T, ten)
    mujoco.mj_forward(model, data)
    assert capstan.anchor_tension(model, data, ten) / T == pytest.approx(1.0, abs=2e-3)


# --------------------------------------------------------------------------- hysteresis
def _loop(model, act, ten, mu: float) -> tuple[float, float]:
    """Static section bend (deg) at the same motor tension reached by loading and by unloading."""
    data = mujoco.MjData(model)
    _slack(model, data)
    handle = fr.install_cable_friction(model, data, fo.CableFrictionConfig(mu=mu))
    top = capstan.tension_for_bend(model, ten, np.radians(80.0))
    mid = 0.55 * top
    _drive(model, data, act, np.linspace(0.0, mid, 250), ten)
    _settle(model, data, act, mid, ten)
    loading = _section_bend(model, data, ten)
    _drive(model, data, act, np.r_[np.linspace(mid, top, 125), np.full(250, top)], ten)
    _drive(model, data, act, np.linspace(top, mid, 125), ten)
    _settle(model, data, act, mid, ten)
    unloading = _section_bend(model, data, ten)
    assert np.abs(data.qvel).max() < 1e-3  # static
    handle.uninstall()
    return float(np.degrees(loading)), float(np.degrees(unloading))


def test_hysteresis_loading_vs_unloading(rig) -> None:
    """Same motor tension, different bends: loading bends less than unloading (friction holds)."""
    model, act, ten = rig
    load0, unload0 = _loop(model, act, ten, 0.0)
    load, unload = _loop(model, act, ten, 0.15)
    assert abs(unload0 - load0) < 0.2  # frictionless: one static shape per tension
    # With μ = 0.15 friction holds the bend on the way back: at ~45° the section's mean
    # tension sits ≈ μθ/2 ≈ 6 % below (loading) or above (unloading) the motor's, so the
    # two bends differ by ≈ 12 % of the bend (≈ 5°).
    assert unload - load > 3.0
    assert load < load0 < unload


# --------------------------------------------------------------- μ = 0 and the guard
def _run(model, data, steps: int = 150) -> np.ndarray:
    rng = np.random.default_rng(0)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    for _ in range(steps):
        data.ctrl[:] = np.clip(
            data.ten_length[: model.nu] - rng.uniform(0.0, 2e-3, model.nu), lo, hi
        )
        mujoco.mj_step(model, data)
    return np.r_[data.qpos, data.qvel]


def test_zero_friction_is_bit_identical_and_the_guard_spares_other_models() -> None:
    """μ = 0 changes nothing; friction on one model never leaks into another one."""
    model = _compile(ModelOptions(joint="hinge_pair", timestep=0.004))
    reference = _run(model, mujoco.MjData(model))
    data0 = mujoco.MjData(model)
    fr.install_cable_friction(model, data0, fo.CableFrictionConfig(mu=0.0))
    np.testing.assert_array_equal(_run(model, data0), reference)
    # another data of the same model (and another model) with friction, live in this process
    other = mujoco.MjData(model)
    handle = fr.install_cable_friction(model, other, fo.CableFrictionConfig(mu=0.2))
    assert mujoco.get_mjcb_passive() is not None
    np.testing.assert_array_equal(_run(model, mujoco.MjData(model)), reference)
    fresh = _compile(
        ModelOptions(joint="hinge_pair", timestep=0.004)
    )  # compiling runs the passive stage too
    np.testing.assert_array_equal(_run(fresh, mujoco.MjData(fresh)), reference)
    assert not np.array_equal(
        _run(model, other), reference
    )  # and it does act where installed
    handle.uninstall()
    del data0, other
    import gc

    gc.collect()
    assert (
        mujoco.get_mjcb_passive() is None
    )  # no registration left: the global callback is handed back


# ------------------------------------------------------------------------ in a run
def test_scenario_records_the_friction_loss_per_cable(tmp_path) -> None:
    """The default run installs friction, records anchor/motor ratios, reports them, cleans up."""
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.runner import run_scenario
    from continuum_sim.scenario.trajectory import Trajectory

    config = ScenarioConfig.default()
    assert config.model.cable_friction.mu == fo.DEFAULT_MU
    metrics = run_scenario(config, tmp_path, stages=("initial", "clamping"))
    assert mujoco.get_mjcb_passive() is None  # removed when the run closed
    trajectory = Trajectory.load(tmp_path / "trajectory.npz")
    ratio = trajectory.arms["right"].cable_anchor_ratio  # the gripper arm moves in these stages
    assert ratio.shape == trajectory.arms["right"].cable_tension.shape
    assert ratio.min() < 0.97 and ratio.max() > 1.03  # reeled-in cables lose tension, paid-out ones gain
    assert np.all(ratio > np.exp(-config.model.cable_friction.mu * np.pi))  # no cable wraps more than 180°
    friction = metrics["cable_friction"]
    assert friction["mu"] == fo.DEFAULT_MU
    all_ratios = np.concatenate([a.cable_anchor_ratio for a in trajectory.arms.values()], axis=1)
    assert friction["anchor_ratio_min"] == pytest.approx(all_ratios.min())
    assert len(friction["anchor_ratio_mean"]["right"]) == ratio.shape[1]
