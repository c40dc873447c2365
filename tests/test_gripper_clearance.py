"""The gripper knock (issue 24): the planned approach keeps the open jaws clear of the plate.

Geometric check on the scene MuJoCo simulates (`scenario.clearance`): every plan sample of the
clamping stage before the jaws close, posed exactly, against the plate's contact geoms. The
pre-issue-24 plan (back-off along the tilted tool axis, 35 mm) drove a pad 1.7 mm into the
sample edge during the joint transfer: the same check must see that, or it proves nothing.
"""

import dataclasses

import pytest

from continuum_sim.model.options import model_geometry
from continuum_sim.scenario.clearance import gripper_approach_clearance
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.scenario.runner import build_scene_model
from continuum_sim.toolpath import SEGMENT_NAMES, plan_task

APPROACH, GRASP = SEGMENT_NAMES.index("approach"), SEGMENT_NAMES.index("grasp")
MIN_CLEARANCE_M = 0.005  # > the open loop's gravity sag at the approach pose (4.9 mm, fidelity notes)


@pytest.fixture(scope="module")
def scene_model():
    return build_scene_model(ScenarioConfig.default())[1]


def _clearance(config, model):
    plan = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    return gripper_approach_clearance(config, plan, model)


def test_default_plan_keeps_the_jaws_clear_of_the_plate(scene_model):
    cl = _clearance(ScenarioConfig.default(), scene_model)
    for seg in (APPROACH, GRASP):
        d, t, pair = cl.min_over(seg)
        assert d >= MIN_CLEARANCE_M, f"{SEGMENT_NAMES[seg]}: {pair} {d * 1e3:.2f} mm at {t:.2f} s"
    # At the end of the grasp move the pads straddle the sample with equal room on both faces.
    assert cl.distance_m[-1] == pytest.approx(0.008, abs=0.001)


def test_check_sees_the_old_knock(scene_model):
    c = ScenarioConfig.default()
    old = dataclasses.replace(c, plan=dataclasses.replace(c.plan, pregrasp_direction="tool_axis", pregrasp_distance=0.035))
    d, t, pair = _clearance(old, scene_model).min_over(APPROACH)
    assert d < -0.001 and pair[1] == "sample" and 2.8 < t < 3.2
