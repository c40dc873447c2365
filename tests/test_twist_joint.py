"""The hinge_triple joint: a twist DoF with the segment's twist spring (ball central joint).

* its exact XYZ decomposition puts every disk where the PCC model puts it (frames and
  cable lengths to round-off), unlike the twist-rigid hinge pair's ~0.1 mm;
* a torque about the tip axis twists the straight arm by T·Σ n_k/k_twist,k (springs in
  series), and a bending moment bends it by the per-axis bending springs — measured on
  the MuJoCo model with the static solver, not computed from the formula;
* a universal central joint has no twist spring: hinge_triple is refused.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from continuum_sim import ArmGeometry, cable_lengths, disk_frames
from continuum_sim.configio import ConfigError
from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model.arm import build_single_arm_model
from continuum_sim.model.options import ModelOptions
from continuum_sim.model.state import set_arm_configuration
from continuum_sim.model.stiffness import strain_limited_geometry
from continuum_sim.validation.statics import StaticSolver

choose_gl_backend()
import mujoco  # noqa: E402

BALL = dataclasses.replace(strain_limited_geometry(ArmGeometry()), central_joint="ball")
OPTIONS = ModelOptions(joint="hinge_triple")


def _compile(root):
    return mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())


def test_hinge_triple_reproduces_the_pcc_model_exactly():
    model = _compile(build_single_arm_model(BALL, OPTIONS))
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"arm/disk_{i}") for i in range(1, BALL.n_disks)]
    for q in (np.array([0.6, 0.4, 0.9, -1.3, 1.1, 2.5]), np.array([1.5, 3.0, 0.2, 0.1, 1.57, -2.0])):
        set_arm_configuration(model, data, BALL, "arm", q, joint="hinge_triple")
        mujoco.mj_kinematics(model, data)
        mujoco.mj_tendon(model, data)
        frames = disk_frames(BALL, q)
        np.testing.assert_allclose(data.xpos[ids], frames[1:, :3, 3], atol=1e-9)
        np.testing.assert_allclose(data.xmat[ids].reshape(-1, 3, 3), frames[1:, :3, :3], atol=1e-9)
        np.testing.assert_allclose(data.ten_length, cable_lengths(BALL, q), atol=1e-9)


def _tip_rotation_under(torque: np.ndarray) -> np.ndarray:
    options = dataclasses.replace(OPTIONS, tendons=False)
    root = build_single_arm_model(BALL, options, gravity=False)
    model = _compile(root)
    data = mujoco.MjData(model)
    tip = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"arm/disk_{BALL.n_disks - 1}")
    wrenches = np.zeros((model.nbody, 6))
    wrenches[tip, 3:] = torque
    result = StaticSolver(model, data).solve(np.zeros(3), wrenches)
    assert result.converged
    rot = data.xmat[tip].reshape(3, 3)
    # small rotation vector of the tip
    return 0.5 * np.array([rot[2, 1] - rot[1, 2], rot[0, 2] - rot[2, 0], rot[1, 0] - rot[0, 1]])


def test_twist_and_bending_compliance_of_the_model_match_the_springs():
    from continuum_sim.model.stiffness import segment_stiffness

    kx, kz = [], []
    for section in BALL.sections:
        stiff = segment_stiffness(BALL, section)
        kx.append(section.n_segments / stiff[0])
        kz.append(section.n_segments / stiff[2])
    torque = 1e-3  # N·m: small, linear regime
    twist = _tip_rotation_under(np.array([0.0, 0.0, torque]))
    assert twist[2] == pytest.approx(torque * sum(kz), rel=1e-3)
    bend = _tip_rotation_under(np.array([torque, 0.0, 0.0]))
    assert bend[0] == pytest.approx(torque * sum(kx), rel=1e-3)
    assert abs(bend[2]) < 1e-6 * abs(bend[0]) + 1e-12


def test_universal_joint_refuses_hinge_triple():
    universal = dataclasses.replace(BALL, central_joint="universal")
    with pytest.raises(ConfigError, match="model.joint"):
        build_single_arm_model(universal, OPTIONS)
