"""Outer-loop gains derived from the plant (continuum_sim.gains; docs/plant.md, "Outer-loop gains from the plant")."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from continuum_sim import gains
from continuum_sim import kinematics as kin
from continuum_sim.configio import ConfigError, from_dict
from continuum_sim.control import ControlConfig
from continuum_sim.control.arm import ArmController
from continuum_sim.model.cable_elasticity import cable_stiffness
from continuum_sim.model.options import model_geometry
from continuum_sim.model.stiffness import joint_stiffness
from continuum_sim.scenario.config import ScenarioConfig


@pytest.fixture(scope="module")
def cfg() -> ScenarioConfig:
    return ScenarioConfig.default()


def test_flexure_stiffness_is_the_joints_in_series(cfg):
    """K_sec = k_joint / n for the model's n joints per section, whatever n is."""
    for n in (5, 10, 20):
        k = gains.section_flexure_stiffness(cfg.arm, 2.0)
        for s in range(cfg.arm.n_sections):
            assert k[s] == pytest.approx(joint_stiffness(cfg.arm, s, n, 2.0) / n, rel=1e-12)


def test_cable_stiffness_in_bending_coordinates_is_three_halves_k_r2(cfg):
    """The distal section sees only its own three cables at radius r: K_cab = (3/2)·k·r² on both axes."""
    k = cable_stiffness(cfg.arm, cfg.model)
    _, k_cab = gains.stiffness_matrices(cfg.arm, k)
    r = cfg.arm.cable_hole_radius
    expected = 1.5 * k[-3:].mean() * r * r
    assert k_cab[4, 4] == pytest.approx(expected, rel=2e-3)
    assert k_cab[5, 5] == pytest.approx(expected, rel=2e-3)
    # Proximal: its own cables plus the six that pass through it.
    assert k_cab[0, 0] == pytest.approx(1.5 * r * r * k.sum() / 3.0, rel=2e-3)


def test_inverse_transmission_is_identity_plus_compliance_ratio(cfg):
    k = cable_stiffness(cfg.arm, cfg.model)
    R = gains.transmission(cfg.arm, k, 3.0)
    R_inv = gains.inverse_transmission(cfg.arm, k, 3.0)
    np.testing.assert_allclose(R @ R_inv, np.eye(6), atol=1e-10)


def _settled_bend(cfg, scale: float, w_cmd: np.ndarray) -> np.ndarray:
    """Achieved bending coordinates of the MuJoCo arm (no gravity) with its motors at the
    set-points of ``w_cmd`` less the pre-tension offsets, read from the tendons' lengths."""
    import mujoco

    from continuum_sim.model.arm import build_single_arm_model

    options = dataclasses.replace(cfg.model, stiffness_scale=scale, cable_friction=cfg.model.cable_friction)
    geometry = model_geometry(cfg.arm, options)
    root = build_single_arm_model(cfg.arm, options, gravity=False)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    data = mujoco.MjData(model)
    k = cable_stiffness(cfg.arm, options)
    offset = cfg.control.pretension / k

    def settle(w: np.ndarray) -> np.ndarray:
        mujoco.mj_resetData(model, data)
        data.ctrl[:] = kin.cable_lengths_bending(geometry, w) - offset
        for _ in range(3000):
            mujoco.mj_step(model, data)
        assert np.abs(data.qvel).max() < 1e-5
        return data.ten_length[:9].copy()

    l0 = settle(np.zeros(6))
    dl = settle(w_cmd) - l0
    A = gains.cable_moment_arms(geometry)
    return np.linalg.lstsq(-A, dl, rcond=None)[0]


@pytest.mark.parametrize("scale", [1.0, 8.0])
def test_transmission_matches_the_mujoco_arm(cfg, scale):
    """R from K_flex and K_cab against the simulated arm: command a small bend of one section, read the achieved one."""
    k = cable_stiffness(cfg.arm, dataclasses.replace(cfg.model, stiffness_scale=scale))
    R = gains.transmission(cfg.arm, k, scale)
    for column in (0, 3):  # proximal u, middle v
        w_cmd = np.zeros(6)
        w_cmd[column] = 0.03
        measured = _settled_bend(cfg, scale, w_cmd) / 0.03
        np.testing.assert_allclose(measured, R[:, column], atol=0.005)
        if scale == 8.0 and column == 0:
            assert R[0, 0] < 0.85  # the check means something: 1 (rigid cables) would fail it


def test_plant_gain_places_every_pole_at_the_crossover_and_scales_with_stiffness(cfg):
    k = cable_stiffness(cfg.arm, cfg.model)
    previous = None
    for scale in (0.5, 1.0, 8.0):
        options = dataclasses.replace(cfg.model, stiffness_scale=scale)
        g = gains.plant_gain(cfg.arm, options, 3.0, 0.5, cfg.control.pretension, k, 0.08, 0.06)
        R = gains.transmission(cfg.arm, k, scale)
        assert not g.capped
        np.testing.assert_allclose(R @ g.matrix, g.crossover * np.eye(6), atol=1e-9)  # the loop: ė = −R G e
        if previous is not None:  # stiffer hinges: less transmission, more gain, a higher first mode
            assert np.all(np.diag(g.matrix) > np.diag(previous.matrix))
            assert g.first_mode > previous.first_mode
            assert g.rho[0] < previous.rho[0]
        previous = g
    capped = gains.plant_gain(cfg.arm, cfg.model, 1000.0, 0.5, cfg.control.pretension, k)
    assert capped.capped and capped.crossover == pytest.approx(0.5 * capped.first_mode)
    assert 0.0 < capped.decay <= capped.modal_decay < capped.first_mode


def test_first_mode_matches_the_validation_eigensolver(cfg):
    """Joints only (no cables): gains.first_mode against validation.statics.linear_natural_frequencies."""
    import mujoco

    from continuum_sim.model.arm import build_single_arm_model
    from continuum_sim.validation.statics import linear_natural_frequencies

    options = dataclasses.replace(cfg.model, tendons=False)
    root = build_single_arm_model(cfg.arm, options, gravity=False)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    reference = 2.0 * np.pi * linear_natural_frequencies(model, data)[0]
    assert gains.first_mode(cfg.arm, options, 0.0) == pytest.approx(reference, rel=1e-4)


def test_arm_controller_with_a_scalar_gain_matrix_equals_the_fixed_gain(cfg):
    geometry = cfg.arm
    control = ControlConfig()
    base = np.eye(4)
    plan_q = np.array([0.3, 0.2, 0.4, -1.0, 0.2, 0.5])
    R_plan = np.eye(3)
    tcp = np.eye(4)
    tcp[:3, 3] = (0.01, 0.02, 0.6)
    results = []
    for gain in (None, control.outer_gain * np.eye(6)):
        arm = ArmController(geometry, control, base, 0.06, 1e5, gain=gain)
        for _ in range(3):
            out = arm.update(plan_q, tcp, np.array([0.012, 0.018, 0.598]), R_plan, 0.008)
        results.append((out, arm.correction.copy()))
    np.testing.assert_allclose(results[0][0], results[1][0], atol=1e-15)
    np.testing.assert_allclose(results[0][1], results[1][1], atol=1e-15)


def test_gain_mode_is_validated_and_loads_from_toml():
    with pytest.raises(ConfigError, match=r"^gain_mode: must be 'fixed' or 'plant' \(got 'auto'\)$"):
        ControlConfig(gain_mode="auto")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="^mode_fraction: "):
        ControlConfig(mode_fraction=0.0)
    with pytest.raises(ConfigError, match="control.gain_mode"):
        from_dict(ScenarioConfig, {"control": {"gain_mode": "adaptive"}})
    loaded = from_dict(ScenarioConfig, {"control": {"gain_mode": "plant", "mode_fraction": 0.2}})
    assert loaded.control.gain_mode == "plant" and loaded.control.mode_fraction == 0.2
