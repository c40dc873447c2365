"""Every section bends to 90° within the motors' force rating (issue 12), checked on the MuJoCo model.

``model.holding.holding_tensions``: the least cable tensions whose tendon forces balance
the joint springs at the PCC pose (gravity off). The cables hold the pose exactly (zero
residual) and the largest tension plus the pre-tension stays within
``model.cable_max_force``, for the shipped segments and for the strain-limited leaves, in
every bending direction. The quasi-static formula ``bend_tension`` agrees with the model
where the bend points at a cable.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest

from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model import holding
from continuum_sim.model.arm import build_single_arm_model
from continuum_sim.model.stiffness import bend_tension, strain_limited_geometry
from continuum_sim.scenario.config import ScenarioConfig

choose_gl_backend()
import mujoco  # noqa: E402

CONFIG = ScenarioConfig.default()
# Ball joints represent the PCC pose exactly (hinge pairs only to second order, which
# leaves a tiny residual that least squares would trade for huge common-mode tensions);
# their bending springs are the same K_x = K_y.
OPTIONS = dataclasses.replace(CONFIG.model, joint="ball")
GEOMETRIES = {"shipped": CONFIG.arm, "strain_limited": strain_limited_geometry(CONFIG.arm)}


@functools.cache
def _model(name: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(build_single_arm_model(GEOMETRIES[name], OPTIONS, gravity=False).to_xml_string())


def holding_tensions(name: str, q: np.ndarray) -> tuple[np.ndarray, float, float]:
    return holding.holding_tensions(_model(name), GEOMETRIES[name], q, OPTIONS.joint)


@pytest.mark.parametrize("name", list(GEOMETRIES))
@pytest.mark.parametrize("section", [0, 1, 2])
def test_each_section_bends_to_90_degrees_within_the_rating(name, section):
    geometry = GEOMETRIES[name]
    worst = 0.0
    for phi_deg in np.arange(0.0, 120.0, 15.0):  # every cable pattern repeats each 120°: one sector covers all directions
        q = np.zeros(2 * geometry.n_sections)
        q[2 * section] = geometry.sections[section].max_bend
        q[2 * section + 1] = math.radians(geometry.sections[section].cable_angles_deg[0] + phi_deg)
        tension, residual, spring = holding_tensions(name, q)
        assert residual < 1e-6 * spring, f"the cables cannot hold the pose (residual {residual:.3g} N·m)"
        worst = max(worst, float(tension.max()))
    assert worst + CONFIG.control.pretension <= CONFIG.model.cable_max_force, (
        f"{name} section {section}: {worst:.1f} N + pre-tension exceeds the rating {CONFIG.model.cable_max_force} N"
    )


def test_bend_tension_formula_matches_the_model_toward_a_cable():
    geometry = GEOMETRIES["strain_limited"]
    for k in range(geometry.n_sections):
        q = np.zeros(2 * geometry.n_sections)
        q[2 * k] = geometry.sections[k].max_bend
        q[2 * k + 1] = math.radians(geometry.sections[k].cable_angles_deg[0])
        tension, _, _ = holding_tensions("strain_limited", q)
        # the pulling cable of the bent section (its first)
        assert tension[3 * k] == pytest.approx(bend_tension(geometry, k), rel=0.01)
