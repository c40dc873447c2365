"""The native cable path (continuum_sim.plant.cable_path) against MuJoCo's own spatial tendons.

The reference is independent of the kernel: MuJoCo's spatial tendons through the hole
sites (lengths, Jacobians, velocities, actuator transmissions and the resulting forces
and accelerations). The native model must give the same numbers to round-off, alone and
with cable friction, in every joint type the arm builder makes; its guard must spare
other models and datas in the process (sweeps, ``mujoco.rollout``).
"""

from __future__ import annotations

import dataclasses
import gc

import mujoco
import numpy as np
import pytest

from continuum_sim.geometry import ArmGeometry
from continuum_sim.model.arm import build_single_arm_model
from continuum_sim.model.friction_options import CableFrictionConfig
from continuum_sim.model.options import ModelOptions
from continuum_sim.plant import cable_path as cp
from continuum_sim.plant import friction as fr
from continuum_sim.plant import passive
from continuum_sim.plant.cable_routing import cable_tendons


def _arm_root(joint: str, timestep: float = 0.004):
    geometry = ArmGeometry.default()
    if joint == "hinge_triple":  # a twist spring needs the central ball joint
        geometry = dataclasses.replace(geometry, central_joint="ball")
    return build_single_arm_model(geometry, ModelOptions(joint=joint, timestep=timestep), gravity=True)


def _random_state(model: mujoco.MjModel, data: mujoco.MjData, rng: np.random.Generator) -> None:
    mujoco.mj_resetData(model, data)
    for j in range(model.njnt):
        a = model.jnt_qposadr[j]
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            rv = rng.normal(size=3) * 0.1
            mujoco.mju_axisAngle2Quat(data.qpos[a : a + 4], rv / np.linalg.norm(rv), np.linalg.norm(rv))
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            data.qpos[a] = rng.normal() * 0.1
    data.qvel[:] = rng.normal(size=model.nv) * 0.2
    # cables taut by 0-2 mm (actuator length set-points below the tendon lengths)
    mujoco.mj_kinematics(model, data)
    data.ctrl[:] = np.clip(model.actuator_ctrlrange.mean(axis=1) - rng.uniform(0.0, 2e-3, model.nu),
                           *model.actuator_ctrlrange.T)


def _dense(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    J = np.zeros((model.ntendon, model.nv))
    mujoco.mju_sparse2dense(J, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind)
    M = np.zeros((model.nu, model.nv))
    mujoco.mju_sparse2dense(M, data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind)
    return J, M


FIELDS = ("ten_length", "ten_velocity", "actuator_length", "actuator_velocity", "actuator_force", "qfrc_passive",
          "qfrc_actuator", "qfrc_constraint", "qacc")


def test_ball_joints_are_refused_with_a_reason() -> None:
    with pytest.raises(ValueError, match="ball joint"):
        cp.compile_native(_arm_root("ball"))


@pytest.mark.parametrize("joint", ["hinge_pair", "hinge_triple"])
def test_native_cables_equal_the_spatial_tendons(joint: str) -> None:
    """Lengths, Jacobians, transmissions and generalized forces to 1e-12 (relative to their scale)."""
    native, spatial = cp.compile_native(_arm_root(joint))
    ids = cable_tendons(spatial)
    assert all(native.wrap_type[native.tendon_adr[t]] == mujoco.mjtWrap.mjWRAP_JOINT for t in ids)  # fixed now
    assert cp.native_cables(native) is not None and cp.native_cables(spatial) is None
    d_native, d_spatial = cp.make_data(native), mujoco.MjData(spatial)
    rng = np.random.default_rng(7)
    for _ in range(3):
        _random_state(spatial, d_spatial, rng)
        mujoco.mj_resetData(native, d_native)
        for name in ("qpos", "qvel", "ctrl"):
            getattr(d_native, name)[:] = getattr(d_spatial, name)
        mujoco.mj_forward(spatial, d_spatial)
        mujoco.mj_forward(native, d_native)
        for name in FIELDS:
            a, b = getattr(d_native, name), getattr(d_spatial, name)
            scale = max(1.0, float(np.max(np.abs(b))))
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * scale, err_msg=name)
        for a, b in zip(_dense(native, d_native), _dense(spatial, d_spatial), strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


def test_shortened_tendons_give_mujoco_the_same_exact_zeros() -> None:
    """``shorten_zero_tendons`` (MuJoCo visits one joint of each cable's fixed tendon, not all):
    MuJoCo's own tendon outputs are the full tendon's bit for bit (zeros), the sparsity is kept."""
    root = _arm_root("hinge_pair")
    xml, assets = root.to_xml_string(), root.get_assets()
    spatial = mujoco.MjModel.from_xml_string(xml, assets)
    ids = cable_tendons(spatial)
    full = mujoco.MjModel.from_xml_string(cp.native_cable_xml(xml, spatial, ids), assets)
    short = mujoco.MjModel.from_xml_string(cp.native_cable_xml(xml, spatial, ids), assets)
    cp.shorten_zero_tendons(short, ids)
    assert np.all(short.tendon_num[ids] == 1) and np.all(full.tendon_num[ids] > 10)
    np.testing.assert_array_equal(short.ten_J_rownnz, full.ten_J_rownnz)
    np.testing.assert_array_equal(short.ten_J_colind, full.ten_J_colind)
    d_full, d_short = mujoco.MjData(full), mujoco.MjData(short)
    rng = np.random.default_rng(3)
    for _ in range(3):
        _random_state(full, d_full, rng)
        d_short.qpos[:], d_short.qvel[:] = d_full.qpos, d_full.qvel
        for m, d in ((full, d_full), (short, d_short)):
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            mujoco.mj_tendon(m, d)
        for name in ("ten_length", "ten_J"):
            np.testing.assert_array_equal(getattr(d_short, name), getattr(d_full, name), err_msg=name)
        assert not np.any(d_full.ten_J) and not np.any(d_full.ten_length[ids])
    with pytest.raises(ValueError, match="zero-coefficient fixed tendon"):
        cp.shorten_zero_tendons(spatial, ids)  # spatial tendons: refused


def _drive(model: mujoco.MjModel, data: mujoco.MjData, steps: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo, hi = model.actuator_ctrlrange.T
    mujoco.mj_forward(model, data)
    for _ in range(steps):
        data.ctrl[:] = np.clip(data.actuator_length - rng.uniform(0.0, 2e-3, model.nu), lo, hi)
        mujoco.mj_step(model, data)
    return np.r_[data.qpos, data.qvel]


@pytest.mark.parametrize("mu", [0.0, 0.15])
def test_native_and_spatial_runs_agree_with_friction(mu: float) -> None:
    """200 implicitfast steps under random taut-cable controls, with and without cable friction:
    same trajectory to round-off (the friction kernel reuses the pieces the native kernel computed)."""
    native, spatial = cp.compile_native(_arm_root("hinge_pair"))
    d_native, d_spatial = cp.make_data(native), mujoco.MjData(spatial)
    config = CableFrictionConfig(mu=mu)
    h_native = fr.install_cable_friction(native, d_native, config)
    h_spatial = fr.install_cable_friction(spatial, d_spatial, config)
    a, b = _drive(native, d_native, 200), _drive(spatial, d_spatial, 200)
    h_native.check()
    h_spatial.check()
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    if mu > 0:
        np.testing.assert_allclose(h_native.anchor_ratio(), h_spatial.anchor_ratio(), rtol=0, atol=1e-9)
        assert np.ptp(h_native.anchor_ratio()) > 1e-3  # friction did act
    h_native.uninstall()
    h_spatial.uninstall()


def test_the_guard_spares_other_models_and_flags_unregistered_data() -> None:
    """A live native model changes nothing for other models (plain steps, mujoco.rollout threads);
    stepping it with an MjData it did not make is reported, not silently wrong."""
    spatial_only = mujoco.MjModel.from_xml_string(_arm_root("hinge_pair").to_xml_string())
    reference = _drive(spatial_only, mujoco.MjData(spatial_only), 100)
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    d_native = cp.make_data(native)
    _drive(native, d_native, 5)  # the callback is live
    assert mujoco.get_mjcb_passive() is not None
    np.testing.assert_array_equal(_drive(spatial_only, mujoco.MjData(spatial_only), 100), reference)

    from mujoco import rollout

    data = mujoco.MjData(spatial_only)
    mujoco.mj_forward(spatial_only, data)
    state0 = np.zeros(mujoco.mj_stateSize(spatial_only, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(spatial_only, data, state0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    ctrl = np.tile(spatial_only.actuator_ctrlrange.mean(axis=1) - 1e-3, (50, 1))
    plain = rollout.rollout(spatial_only, [mujoco.MjData(spatial_only) for _ in range(2)], np.tile(state0, (2, 1)),
                            np.tile(ctrl, (2, 1, 1)))[0]
    with_native_live = rollout.rollout(spatial_only, [mujoco.MjData(spatial_only) for _ in range(2)],
                                       np.tile(state0, (2, 1)), np.tile(ctrl, (2, 1, 1)))[0]
    np.testing.assert_array_equal(plain, with_native_live)

    passive.raise_pending()  # nothing flagged so far
    stray = mujoco.MjData(native)  # not from make_data
    mujoco.mj_forward(native, stray)
    with pytest.raises(RuntimeError, match="native cables"):
        passive.raise_pending()
    del d_native, stray
    gc.collect()


def test_native_model_is_dropped_with_its_model() -> None:
    """The dispatch does not keep freed models (sweeps build many in one process)."""
    native, spatial = cp.compile_native(_arm_root("hinge_pair"))
    address = native._address
    assert address in passive._DISPATCH.native_models
    del native, spatial
    gc.collect()
    assert address not in passive._DISPATCH.native_models


def test_two_datas_of_one_model_stepped_in_two_threads_do_not_share_scratch() -> None:
    """The kernels run without the GIL (compiled callback, ``nogil`` kernels): each registered data
    has its own piece scratch, so two threads stepping two datas of one native model (with cable
    friction reading the pieces) give each data's single-threaded trajectory bit for bit."""
    import threading

    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    cables = cp.native_cables(native)
    assert cables is not None
    datas = [cp.make_data(native) for _ in range(2)]
    handles = [fr.install_cable_friction(native, d, CableFrictionConfig(mu=0.15)) for d in datas]
    assert handles[0].pieces.length is not handles[1].pieces.length

    def run(data: mujoco.MjData, seed: int, out: list[np.ndarray]) -> None:
        out.append(_drive(native, data, 300, seed=seed))

    alone: list[np.ndarray] = []
    for seed, data in enumerate(datas):
        mujoco.mj_resetData(native, data)
        run(data, seed, alone)
    together: list[list[np.ndarray]] = [[], []]
    for data in datas:
        mujoco.mj_resetData(native, data)
    for h in handles:
        h.z[:] = 0.0
        h.initialised[:] = False
    threads = [threading.Thread(target=run, args=(d, seed, together[seed])) for seed, d in enumerate(datas)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for h in handles:
        h.check()
        h.uninstall()
    for seed in range(2):
        np.testing.assert_array_equal(together[seed][0], alone[seed])
    for d in datas:
        cp.release_data(d)
        assert passive.runtime_of(d) is None
