"""The generated arm model against the kinematic model it must reproduce (SPEC §6)."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from continuum_sim import cable_lengths, disk_frames, forward_kinematics
from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model.arm import build_single_arm_model
from continuum_sim.model.options import ModelOptions, model_geometry
from continuum_sim.model.state import set_arm_configuration
from conftest import random_q

choose_gl_backend()
import mujoco  # noqa: E402


def compile_model(root):
    return mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())


def body_ids(model, n):
    return [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"arm/disk_{i}") for i in range(1, n + 1)]


@pytest.mark.parametrize("segments", [0, 4, 13])
def test_tendon_lengths_and_disk_frames_equal_kinematics(geometry, segments):
    options = ModelOptions(segments_per_section=segments)
    geom = model_geometry(geometry, options)
    model = compile_model(build_single_arm_model(geometry, options, "grinder"))
    data = mujoco.MjData(model)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, i) for i in range(model.ntendon)]
    assert names == geometry.cable_names("arm")
    ids = body_ids(model, geom.n_disks - 1)
    tcp = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "arm/tcp")
    rng = np.random.default_rng(10 + segments)
    for q in random_q(rng, geom, 25):
        set_arm_configuration(model, data, geom, "arm", q)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_tendon(model, data)
        np.testing.assert_allclose(data.ten_length, cable_lengths(geom, q), atol=1e-9, rtol=0)
        frames = disk_frames(geom, q)
        np.testing.assert_allclose(data.xpos[ids], frames[1:, :3, 3], atol=1e-9, rtol=0)
        np.testing.assert_allclose(data.xmat[ids].reshape(-1, 3, 3), frames[1:, :3, :3], atol=1e-9, rtol=0)
        tip = forward_kinematics(geom, q)
        np.testing.assert_allclose(data.site_xpos[tcp], tip[:3, 3] + geometry.tools.grinder_length * tip[:3, 2], atol=1e-9)


def test_hinge_pair_points_disks_like_the_pcc_model(geometry):
    options = ModelOptions(joint="hinge_pair")
    model = compile_model(build_single_arm_model(geometry, options))
    data = mujoco.MjData(model)
    ids = body_ids(model, geometry.n_disks - 1)
    q = np.array([0.6, 0.4, 0.9, -1.3, 1.1, 2.5])
    set_arm_configuration(model, data, geometry, "arm", q, joint="hinge_pair")
    mujoco.mj_kinematics(model, data)
    mujoco.mj_tendon(model, data)
    # Same pointing per joint; the universal joints' second-order twist cancels between
    # consecutive joints (alternating x-y / y-x order), leaving ~0.1 mm at the tip and ~1 µm
    # in the cables at this large bend (without alternation: 1.3 mm and 20 µm).
    np.testing.assert_allclose(data.xpos[ids[-1]], forward_kinematics(geometry, q)[:3, 3], atol=0.3e-3)
    np.testing.assert_allclose(data.ten_length, cable_lengths(geometry, q), atol=3e-6)


def test_joint_stiffness_scales_with_segment_count(geometry):
    stiff = {}
    for n in (5, 10, 20):
        model = compile_model(build_single_arm_model(geometry, ModelOptions(segments_per_section=n)))
        stiff[n] = model.jnt_stiffness[0]
    assert stiff[10] == pytest.approx(2 * stiff[5]) and stiff[20] == pytest.approx(4 * stiff[5])


def test_cables_never_push_under_random_commands(geometry):
    options = ModelOptions()
    model = compile_model(build_single_arm_model(geometry, options, "gripper"))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    low, high = model.actuator_ctrlrange.T
    max_force = 0.0
    for step in range(3000):
        if step % 100 == 0:
            data.ctrl[:] = rng.uniform(low + 0.1, high - 0.1)
        mujoco.mj_step(model, data)
        max_force = max(max_force, float(data.actuator_force.max()))
        assert data.actuator_force.min() >= -options.cable_max_force - 1e-9
    assert max_force <= 0.0
    assert np.all(np.isfinite(data.qpos))


def _fit_pcc(geom, lengths, q0):
    def residual(w):
        q = np.empty(6)
        q[0::2] = np.hypot(w[0::2], w[1::2])
        q[1::2] = np.arctan2(w[1::2], w[0::2])
        return cable_lengths(geom, q) - lengths

    w0 = np.empty(6)
    w0[0::2] = q0[0::2] * np.cos(q0[1::2])
    w0[1::2] = q0[0::2] * np.sin(q0[1::2])
    w = least_squares(residual, w0, xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    q = np.empty(6)
    q[0::2] = np.hypot(w[0::2], w[1::2])
    q[1::2] = np.arctan2(w[1::2], w[0::2])
    return q


@pytest.mark.parametrize("q_deg", [(30, 0, 0, 0, 0, 0), (20, 45, 35, 200, 40, 100), (0, 0, 50, 90, 60, 300)])
def test_cable_actuation_gives_constant_curvature_sections(geometry, q_deg):
    """Gravity off, cables pulled to a PCC shape: the arm settles into constant-curvature
    sections, and its tip is where PCC puts it for the realised cable lengths (≤ 0.5 mm)."""
    options = ModelOptions()
    model = compile_model(build_single_arm_model(geometry, options, gravity=False))
    data = mujoco.MjData(model)
    q = np.radians(q_deg)
    pretension = 20.0  # N, so no cable goes slack
    data.ctrl[:] = cable_lengths(geometry, q) - pretension / options.cable_kp
    for _ in range(6000):
        mujoco.mj_step(model, data)
    assert np.abs(data.qvel).max() < 2e-3, "not settled"
    assert data.actuator_force.max() < 0.0, "a cable went slack"
    q_fit = _fit_pcc(geometry, data.ten_length.copy(), q)
    tip_sim = data.xpos[body_ids(model, geometry.n_disks - 1)[-1]]
    tip_pcc = forward_kinematics(geometry, q_fit)[:3, 3]
    assert np.linalg.norm(tip_sim - tip_pcc) < 0.5e-3
    assert np.linalg.norm(tip_sim - forward_kinematics(geometry, q)[:3, 3]) < 5e-3
