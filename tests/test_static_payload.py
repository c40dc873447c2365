"""The static evaluations carry the tool: its mass is in the model, and its weight sags the arm.

The check of the sag: the arm with the tool payload sags exactly as the same arm without
it under an explicit wrench equal to the tool's weight (configured mass × g) at the
tool's centre of mass — the extra force and the extra moment about the tip.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model.arm import build_single_arm_model
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.sweep import static
from continuum_sim.sweep.evaluations import GravitySag, TipDeflection
from continuum_sim.sweep.payload import tool_payload

choose_gl_backend()
import mujoco  # noqa: E402

CONFIG = ScenarioConfig.default()
SAG = GravitySag(q_deg=(60.0, 0.0, 30.0, 0.0, 0.0, 0.0), tool="grinder", settle_s=1.5)


@pytest.mark.parametrize("tool, mass_field", [("grinder", "grinder_mass"), ("gripper", "gripper_mass")])
def test_payload_is_the_configured_tool(tool, mass_field):
    payload = tool_payload(CONFIG, tool)
    assert payload.mass == pytest.approx(getattr(CONFIG.model, mass_field), rel=1e-12)
    # centre of mass on the tool axis, between the mount and the tool centre point
    assert abs(payload.com[0]) < 1e-3 and abs(payload.com[1]) < 1e-3
    assert 0.0 < payload.com[2] < CONFIG.arm.tools.length(tool)
    model = static.build_model(CONFIG, dataclasses.replace(SAG, tool=tool))
    bare = static.build_model(CONFIG, dataclasses.replace(SAG, tool="none"))
    assert model.body_mass.sum() - bare.body_mass.sum() == pytest.approx(payload.mass, rel=1e-9)


def test_tip_deflection_carries_its_tool_too():
    ev = TipDeflection(tool="gripper", settle_s=0.1)
    assert static.payload_mass(static.build_model(CONFIG, ev)) == pytest.approx(CONFIG.model.gripper_mass)
    assert static.payload_mass(static.build_model(CONFIG, dataclasses.replace(ev, tool="none"))) == 0.0


def _sag_with_wrench(mass: float, com_local: np.ndarray) -> float:
    """Gravity sag of the arm without a payload, loaded by mass·g at ``com_local`` (tip-disk frame)."""
    options = static.model_options(CONFIG, SAG)
    root = build_single_arm_model(CONFIG.arm, options, "grinder")  # the same TCP site, no payload
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    case = static.prepare(model, CONFIG, SAG)
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, case.initial, static.FULL)
    mujoco.mj_forward(model, data)
    tip = case.tip_body
    weight = mass * np.asarray(model.opt.gravity)
    point = data.xpos[tip] + data.xmat[tip].reshape(3, 3) @ com_local
    wrench = np.concatenate([weight, np.cross(point - data.xipos[tip], weight)])
    spec = static.CTRL | static.XFRC
    inputs = []
    for loaded in (False, True):
        data.ctrl[:] = case.ctrl
        data.xfrc_applied[:] = 0.0
        if loaded:
            data.xfrc_applied[tip] = wrench
        vec = np.empty(mujoco.mj_stateSize(model, spec))
        mujoco.mj_getState(model, data, vec, spec)
        inputs.append(vec)
    case = dataclasses.replace(case, control_spec=spec, inputs=(inputs[0], inputs[1]))
    (result,) = static.simulate([case])
    return result["sag_mm"]


def test_gravity_sag_with_the_tool_matches_its_weight_and_moment():
    with_tool = static.evaluate_static(CONFIG, SAG)
    without = static.evaluate_static(CONFIG, dataclasses.replace(SAG, tool="none"))
    assert with_tool["payload_kg"] == pytest.approx(CONFIG.model.grinder_mass)
    assert without["payload_kg"] == 0.0
    payload = tool_payload(CONFIG, "grinder")
    expected = _sag_with_wrench(CONFIG.model.grinder_mass, np.asarray(payload.com))
    assert with_tool["sag_mm"] > 1.2 * _sag_with_wrench(0.0, np.zeros(3))  # the tool's share is not small
    assert with_tool["sag_mm"] == pytest.approx(expected, rel=0.03)
    # a weight at the tip disk centre alone (no lever) would understate it
    assert _sag_with_wrench(CONFIG.model.grinder_mass, np.zeros(3)) < expected
