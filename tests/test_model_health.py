"""Menagerie-style health check of every generated model.

Each model steps 5 s of simulated time under seeded random (but physical) commands: the
arms' cables follow random PCC shapes (smoothly interpolated, with pre-tension), the
gripper opens and closes, the spindle changes speed. It must raise no MuJoCo warning
(``data.warning`` counters), keep a finite state, and keep every tool centre point
within reach of its arm.
"""

from pathlib import Path

import numpy as np
import pytest

from continuum_sim import ArmGeometry, cable_lengths
from continuum_sim.layout import TaskLayout
from continuum_sim.model.arm import build_single_arm_model
from continuum_sim.model.options import ModelOptions, model_geometry
from continuum_sim.model.scene import build_scene
from continuum_sim.model.tools import ToolOptions

import mujoco  # noqa: E402  (the scene module chose the GL backend first)

MODELS = Path(__file__).resolve().parent.parent / "models"
DURATION = 5.0
WAYPOINT_EVERY = 0.5
PRETENSION = 10.0  # N


def _compile(root) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())


CASES = {
    "arm.xml": lambda: mujoco.MjModel.from_xml_path(str(MODELS / "arm.xml")),
    "dual_arm.xml": lambda: mujoco.MjModel.from_xml_path(str(MODELS / "dual_arm.xml")),
    "arm-hinge_pair": lambda: _compile(build_single_arm_model(ArmGeometry(), ModelOptions(joint="hinge_pair"), "none")),
    "dual_arm-hinge_pair": lambda: _compile(build_scene(ArmGeometry(), TaskLayout(), ModelOptions(joint="hinge_pair"))),
}


def random_waypoints(rng, geometry, n):
    q = np.zeros((n, 2 * geometry.n_sections))
    q[1:, 0::2] = rng.uniform(0.0, 0.5, (n - 1, geometry.n_sections)) * geometry.max_bend
    q[1:, 1::2] = rng.uniform(-np.pi, np.pi, (n - 1, geometry.n_sections))
    return q


@pytest.mark.parametrize("case", list(CASES))
def test_model_steps_cleanly_under_random_commands(case):
    model = CASES[case]()
    data = mujoco.MjData(model)
    geometry = model_geometry(ArmGeometry(), ModelOptions())  # all cases use the physical segment count
    rng = np.random.default_rng(sum(map(ord, case)))
    arms = [a for a in ("arm", "left", "right") if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{a}/tcp") >= 0]
    assert arms
    n_way = int(DURATION / WAYPOINT_EVERY) + 2
    # bending coordinates interpolate smoothly through θ = 0
    plans = {}
    for arm in arms:
        q = random_waypoints(rng, geometry, n_way)
        plans[arm] = np.stack([q[:, 0::2] * np.cos(q[:, 1::2]), q[:, 0::2] * np.sin(q[:, 1::2])], axis=-1)
    cables = {a: [model.actuator(n).id for n in geometry.cable_names(a)] for a in arms}
    kp = ModelOptions().cable_kp
    tools = ToolOptions()
    extras = {}
    for name in ("left/grinder/spindle", "right/gripper/cable"):
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name) >= 0:
            extras[name] = model.actuator(name).id
    reach = geometry.length + max(geometry.tools.grinder_length, geometry.tools.gripper_length) + 0.01
    mujoco.mj_forward(model, data)
    bases = {a: data.body(f"{a}/base").xpos.copy() for a in arms}
    straight = {a: data.site(f"{a}/tcp").xpos.copy() for a in arms}
    moved = dict.fromkeys(arms, 0.0)
    steps_per_control = 4
    step = 0
    while data.time < DURATION:
        if step % steps_per_control == 0:
            s = data.time / WAYPOINT_EVERY
            i, f = int(s), s - int(s)
            f = f * f * (3 - 2 * f)
            for arm in arms:
                uv = (1 - f) * plans[arm][i] + f * plans[arm][i + 1]
                theta = np.linalg.norm(uv, axis=1)
                q = np.column_stack([theta, np.arctan2(uv[:, 1], uv[:, 0])]).ravel()
                data.ctrl[cables[arm]] = cable_lengths(geometry, q) - PRETENSION / kp
            if "left/grinder/spindle" in extras and i % 2 == 0 and f < 0.01:
                data.ctrl[extras["left/grinder/spindle"]] = rng.uniform(0, tools.spindle_max_speed)
            if "right/gripper/cable" in extras and f < 0.01:
                data.ctrl[extras["right/gripper/cable"]] = rng.choice([tools.gripper_cable_open, tools.gripper_cable_closed])
        mujoco.mj_step(model, data)
        step += 1
        if step % 100 == 0:
            for arm in arms:
                moved[arm] = max(moved[arm], float(np.linalg.norm(data.site(f"{arm}/tcp").xpos - straight[arm])))
    warnings = {mujoco.mjtWarning(i).name: w.number for i, w in enumerate(data.warning) if w.number}
    assert not warnings, warnings
    for field in ("qpos", "qvel", "qacc", "ctrl", "actuator_force"):
        assert np.all(np.isfinite(getattr(data, field))), field
    for arm in arms:
        assert np.linalg.norm(data.site(f"{arm}/tcp").xpos - bases[arm]) < reach
        assert moved[arm] > 0.05  # the commands really bent the arm
    assert data.time >= DURATION
