"""Motor-loop control of one arm: open loop (paper) vs closed task-space loop (ours)."""

import numpy as np
import pytest

from continuum_sim import ArmGeometry, ConfigError, tool_centre_pose
from continuum_sim.control import ArmController, ControlConfig
from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model.arm import build_single_arm_model
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
    controller = ArmController(geometry, config, np.eye(4), geometry.tools.grinder_length, options.cable_kp)
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
