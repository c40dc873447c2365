"""Motor-loop control of one arm: open loop (paper) vs closed task-space loop (ours)."""

import numpy as np
import pytest

from continuum_sim import ArmGeometry, ConfigError, tool_centre_pose
from continuum_sim.control import ControlConfig
from continuum_sim.control.arm import ArmController
from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model.arm import build_single_arm_model
from continuum_sim.model.cable_elasticity import cable_stiffness
from continuum_sim.scenario.config import ScenarioConfig

choose_gl_backend()
import mujoco  # noqa: E402


def hold_pose(mode: str, seconds: float = 6.0):
    geometry = ArmGeometry.default()
    options = ScenarioConfig().model  # the fidelity the controller is tuned for
    root = build_single_arm_model(geometry, options, "grinder")
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    data = mujoco.MjData(model)
    tcp = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "arm/tcp")
    q = np.radians([30, 0, 40, 180, 50, 90])
    target = tool_centre_pose(geometry, q, "grinder")
    config = ControlConfig(mode=mode)
    controller = ArmController(geometry, config, np.eye(4), geometry.tools.grinder_length, cable_stiffness(geometry, options))
    every = int(round(1.0 / (config.rate_hz * model.opt.timestep)))
    min_tension = np.inf
    for step in range(int(seconds / model.opt.timestep)):
        if step % every == 0:
            data.ctrl[:] = controller.update(q, target, data.site_xpos[tcp], data.site_xmat[tcp], every * model.opt.timestep)
        mujoco.mj_step(model, data)
        if data.time > 1.0:
            min_tension = min(min_tension, -data.actuator_force.max())
    return np.linalg.norm(data.site_xpos[tcp] - target[:3, 3]), min_tension


def test_closed_loop_removes_the_gravity_sag_that_open_loop_keeps():
    open_error, open_tension = hold_pose("open")
    closed_error, closed_tension = hold_pose("closed")
    assert open_error > 2e-3, f"open loop should sag under gravity (got {open_error * 1e3:.3f} mm)"
    assert closed_error < 0.05e-3, f"closed loop error {closed_error * 1e3:.4f} mm"
    assert open_tension > 0.0 and closed_tension > 0.0  # pre-tension keeps every cable taut


def test_control_config_rejects_nonsense():
    with pytest.raises(ConfigError, match="mode: must be 'open' or 'closed'"):
        ControlConfig(mode="fuzzy")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="rate_hz"):
        ControlConfig(rate_hz=0.0)
    with pytest.raises(ConfigError, match="min_tension: must satisfy 0 <= min_tension"):
        ControlConfig(min_tension=-1.0)
    with pytest.raises(ConfigError, match="tension_gain"):
        ControlConfig(tension_gain=float("nan"))


def test_holding_keeps_the_command_the_grasp_closed_on():
    """While the tool holds a fixed object the set-points stay where they were, whatever the
    measured pose: no integration against the grasp, no step when it starts."""
    from continuum_sim import kinematics as kin

    geometry = ArmGeometry.default()
    controller = ArmController(geometry, ControlConfig(), np.eye(4), geometry.tools.gripper_length, 3.0e4)
    q = np.radians([30, 0, 40, 180, 50, 90])
    target = tool_centre_pose(geometry, q, "gripper")
    off = target[:3, 3] + [0.002, -0.001, 0.001]
    free = controller.update(q, target, off, target[:3, :3], 0.008)
    first = controller.update(q, target, off, target[:3, :3], 0.008, holding=True)
    # Holding starts: the proportional share is folded into the correction (no jump).
    np.testing.assert_allclose(first, free, atol=1e-12)
    for _ in range(20):
        held = controller.update(q, target, off + 0.01, kin.exp_so3([0.1, 0, 0]) @ target[:3, :3], 0.008, holding=True)
        np.testing.assert_allclose(held, first, atol=1e-15)
    released = controller.update(q, target, off, target[:3, :3], 0.008)
    assert np.max(np.abs(released - first)) > 1e-6  # integrating again once free


def test_roll_free_loop_ignores_a_roll_about_the_tool_axis():
    """The grinder's loop corrects the tool point and axis, never a roll about the axis."""
    from continuum_sim import kinematics as kin

    geometry = ArmGeometry.default()
    q = np.radians([30, 0, 40, 180, 50, 90])
    target = tool_centre_pose(geometry, q, "grinder")
    rolled = target[:3, :3] @ kin.exp_so3([0.0, 0.0, 0.05])  # 3° about the tool's own z
    tilted = target[:3, :3] @ kin.exp_so3([0.05, 0.0, 0.0])  # 3° of axis error
    for roll_free, expect_roll_response in ((True, False), (False, True)):
        controller = ArmController(geometry, ControlConfig(), np.eye(4), geometry.tools.grinder_length, 3.0e4, roll_free=roll_free)
        rest = controller.update(q, target, target[:3, 3], target[:3, :3], 0.0)
        after_roll = controller.update(q, target, target[:3, 3], rolled, 0.008)
        assert (np.max(np.abs(after_roll - rest)) > 1e-7) == expect_roll_response
        controller = ArmController(geometry, ControlConfig(), np.eye(4), geometry.tools.grinder_length, 3.0e4, roll_free=roll_free)
        controller.update(q, target, target[:3, 3], target[:3, :3], 0.0)
        after_tilt = controller.update(q, target, target[:3, 3], tilted, 0.008)
        assert np.max(np.abs(after_tilt - rest)) > 1e-7  # an axis error is always corrected


def test_tension_keeping_shortens_only_the_slack_section_in_common_mode():
    geometry = ArmGeometry.default()
    config = ControlConfig(min_tension=3.0, tension_gain=5.0, max_extra_tension=30.0)
    controller = ArmController(geometry, config, np.eye(4), geometry.tools.grinder_length, 3.0e4)
    q = np.radians([30, 0, 40, 180, 50, 90])
    target = tool_centre_pose(geometry, q, "grinder")
    before = controller.update(q, target, target[:3, 3], target[:3, :3], 0.0)
    tensions = np.full(9, 10.0)
    tensions[4] = 0.0  # one middle-section cable slack
    after = controller.update(q, target, target[:3, 3], target[:3, :3], 0.008, tensions=tensions)
    shift = before - after
    expected = 5.0 * 3.0 / 3.0e4 * 0.008  # gain · deficit / kp · dt
    np.testing.assert_allclose(shift[3:6], expected, rtol=1e-9)  # the middle section's three cables, equally
    np.testing.assert_allclose(shift[[0, 1, 2, 6, 7, 8]], 0.0, atol=1e-15)
    for _ in range(5000):  # bounded by max_extra_tension / kp
        controller.update(q, target, target[:3, 3], target[:3, :3], 0.008, tensions=tensions)
    assert controller.extra[1] == pytest.approx(30.0 / 3.0e4)
    # Open loop is the paper's method: no tension keeping.
    open_loop = ArmController(geometry, ControlConfig(mode="open"), np.eye(4), geometry.tools.grinder_length, 3.0e4)
    open_loop.update(q, target, target[:3, 3], target[:3, :3], 0.008, tensions=tensions)
    assert not open_loop.extra.any()
