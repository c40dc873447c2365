"""The worked example of docs/architecture.md: a physics effect tested against an oracle (MuJoCo's own damping)."""

from types import SimpleNamespace

import numpy as np
import pytest

from continuum_sim.model.arm import build_single_arm_model
from continuum_sim.model.options import ModelOptions, model_geometry
from examples.joint_drag import JointDrag, disk_dofs

import mujoco  # noqa: E402  (after continuum_sim, which chose the GL backend)


def test_joint_drag_equals_mujocos_joint_damping(geometry):
    options = ModelOptions(joint="hinge_pair")
    xml = build_single_arm_model(model_geometry(geometry, options), options).to_xml_string()
    model, oracle = mujoco.MjModel.from_xml_string(xml), mujoco.MjModel.from_xml_string(xml)
    dofs = np.flatnonzero(model.jnt_type[model.dof_jntid] == mujoco.mjtJoint.mjJNT_HINGE)
    assert len(dofs) > 30
    b = 2.5e-3
    oracle.dof_damping[:] = 0.0
    oracle.tendon_damping[:] = 0.0  # the cables' own damping is not the effect under test
    oracle.dof_damping[dofs] = b
    model.dof_damping[:] = 0.0
    data, expected = mujoco.MjData(model), mujoco.MjData(oracle)
    drag = JointDrag(b, dofs)
    sim = SimpleNamespace(model=model, data=data)
    drag.start(sim)
    rng = np.random.default_rng(0)
    for _ in range(3):  # each step replaces the drag's own share of qfrc_applied, never accumulates it
        data.qvel[:] = expected.qvel[:] = rng.normal(0.0, 2.0, model.nv)
        drag.before_physics_step(sim)
        mujoco.mj_forward(oracle, expected)
        np.testing.assert_allclose(data.qfrc_applied, expected.qfrc_damper, rtol=1e-12, atol=0.0)
    assert disk_dofs(model, np.array([1])).size == model.body_dofnum[1]
    with pytest.raises(ValueError, match="coefficient"):
        JointDrag(-1.0)
