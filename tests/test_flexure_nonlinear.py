"""The nonlinear flexure model: the leaf rod against textbook limits, the plant's curve and its MuJoCo effect."""

from __future__ import annotations

import math

import numpy as np
import pytest

from continuum_sim.configio import ConfigError
from continuum_sim.geometry import ArmGeometry
from continuum_sim.model.options import ModelOptions
from continuum_sim.plant import flexure
from continuum_sim.plant.leaf_rod import SHIPPED, FlexureSegment, LeafSection, Rod, leaf_table, section_segment, table_name
from continuum_sim.validation.flexure_nonlinear import (
    bisshopp_drucker,
    cantilever_tip,
    column_load,
    euler_clamped_load,
    leaf_hand_slope,
)

PETG = dict(youngs_modulus=2.0e9, poisson_ratio=0.38)


def test_bisshopp_drucker_formula_matches_the_published_table() -> None:
    # Bisshopp & Drucker (1945), α = PL²/EI = 1: tip deflection 0.3017 L, tip shortening 0.0566 L
    from scipy.optimize import brentq

    slope = brentq(lambda t: bisshopp_drucker(t)[0] - 1.0, 0.05, 1.5)
    _, delta, shortening = bisshopp_drucker(slope)
    assert delta == pytest.approx(0.3017, abs=2e-4)
    assert shortening == pytest.approx(0.0566, abs=3e-4)


def test_cantilever_large_deflection_matches_bisshopp_drucker() -> None:
    rod = Rod(LeafSection(0.006, 0.0005, **PETG), 0.05, 12)
    alpha, delta, shortening = bisshopp_drucker(0.7817)  # α ≈ 2: a 45° tip slope, far from linear
    p, dz, tip = cantilever_tip(rod, delta * rod.length)
    assert p * rod.length**2 / (PETG["youngs_modulus"] * rod.section.i_tangential_axis) == pytest.approx(alpha, rel=0.01)
    assert dz / rod.length == pytest.approx(shortening, rel=0.02)
    assert tip == pytest.approx(0.7817, rel=0.01)


def test_clamped_column_buckles_at_the_euler_load() -> None:
    section = LeafSection(0.006, 0.0002, **PETG)  # L/t 250: shear and extension negligible
    rod = Rod(section, 0.05, 16, bow=5e-7)
    pe = euler_clamped_load(section, rod.length)
    critical = pe / (PETG["youngs_modulus"] * section.area) * rod.length
    assert column_load(rod, 0.5 * critical) / pe == pytest.approx(0.5, rel=0.01)  # before: a bar, EA·δ/L
    assert column_load(rod, 1.5 * critical) / pe == pytest.approx(1.0, abs=0.03)  # after: the load stays at π²EI/(0.5L)²


def test_small_rotation_slope_matches_hand_beam_stiffness() -> None:
    segment = FlexureSegment(LeafSection(0.006, 0.001, **PETG), 0.018, 0.0029, elements=8, bow_fraction=0.0)
    theta = np.radians([0.001])
    for psi in (0.0, math.pi / 2, math.radians(30.0)):
        m = segment.leaf_curve(theta, psi)[0]
        axis = np.array([math.cos(psi), math.sin(psi)])
        assert m @ axis / theta[0] == pytest.approx(leaf_hand_slope(segment, psi), rel=0.01)
        # at 0° and 90° the axes are principal: no moment off the turning axis to first order
        # (what remains is the θ² shortening of the leaf under the mid-gap joint times its lever)
        if psi in (0.0, math.pi / 2):
            assert abs(m @ np.array([-axis[1], axis[0]])) < 1e-3 * abs(m @ axis)


def _grid() -> tuple[float, int, int]:
    n_psi = int(round(180.0 / flexure.PHI_STEP_DEG)) + 1
    n_theta = int(round(flexure.THETA_MAX_DEG / flexure.THETA_STEP_DEG)) + 1
    return math.radians(flexure.THETA_MAX_DEG), n_theta, n_psi


def test_shipped_tables_match_a_fresh_solve() -> None:
    geometry = ArmGeometry()
    theta_max, n_theta, n_psi = _grid()
    section = geometry.sections[2]
    segment = section_segment(geometry, section)
    assert (SHIPPED / table_name(segment, theta_max, n_theta, n_psi)).exists()
    theta, psi, table = leaf_table(segment, theta_max, n_theta, n_psi)
    j = int(np.argmin(np.abs(psi - math.pi / 2)))  # the compressed leaf
    fresh = segment.leaf_curve(theta[:9], psi[j])
    np.testing.assert_allclose(table[j, :9], fresh, rtol=1e-6, atol=1e-9)


def test_section_curve_is_linear_at_small_rotation_and_threefold_symmetric() -> None:
    geometry = ArmGeometry()
    curve = flexure.section_curve(geometry, geometry.sections[0])
    s = np.radians(0.5) * np.array([0.6, 0.8])
    np.testing.assert_allclose(curve.moment(s), np.array(curve.linear) * s, rtol=0.02)
    rot = np.array([[math.cos(2 * math.pi / 3), -math.sin(2 * math.pi / 3)], [math.sin(2 * math.pi / 3), math.cos(2 * math.pi / 3)]])
    s = np.radians(6.0) * np.array([0.0, 1.0])
    np.testing.assert_allclose(curve.moment(rot @ s), rot @ curve.moment(s), rtol=1e-9, atol=1e-12)
    # the leaf at 0° compressed (φ 90°) buckles first: softer than the opposite direction
    assert curve.moment(s) @ s < curve.moment(-s) @ -s < curve.linear[0] * s @ s


def test_mujoco_effect_applies_the_table_torque() -> None:
    import mujoco

    from continuum_sim.model.arm import build_single_arm_model
    from continuum_sim.plant.flexure import flexure_effect

    geometry = ArmGeometry()
    options = ModelOptions(joint="hinge_pair", tendons=False, flexure_model="nonlinear")
    root = build_single_arm_model(geometry, options, gravity=False)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    data = mujoco.MjData(model)
    effect = flexure_effect(model, ("arm",), geometry, geometry, options.stiffness_scale)
    # joint 2 (section 0, order Ry·Rx) at 6° about y: the grid point (θ 6°, φ 90°)
    jx, jy = (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"arm/joint_2_{a}") for a in "xy")
    data.qpos[model.jnt_qposadr[jy]] = math.radians(6.0)
    mujoco.mj_forward(model, data)
    effect.apply(data)
    effect.apply(data)  # a second step at the same pose replaces its own share, does not add to it
    added = data.qfrc_applied.copy()
    # expected from the leaf table directly: three leaves at ψ = 90°, −30° (90° − 120°), −150° → mirrored to −30°
    theta_max, n_theta, n_psi = _grid()
    _, psi, leaf = leaf_table(section_segment(geometry, geometry.sections[0]), theta_max, n_theta, n_psi)
    i6 = int(round(6.0 / flexure.THETA_STEP_DEG))
    total = np.zeros(2)
    for alpha_deg, psi_deg, mirror in ((0.0, 90.0, False), (120.0, -30.0, False), (240.0, -30.0, True)):
        m = leaf[int(np.argmin(np.abs(np.degrees(psi) - psi_deg))), i6].copy()
        if mirror:
            m[0] = -m[0]
        a = math.radians(alpha_deg)
        total += np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]) @ m
    k = model.jnt_stiffness[jy]
    assert added[model.jnt_dofadr[jy]] == pytest.approx(-(total[1] - k * math.radians(6.0)), rel=1e-9)
    assert added[model.jnt_dofadr[jx]] == pytest.approx(-total[0], abs=1e-9)
    others = np.delete(added, [model.jnt_dofadr[jx], model.jnt_dofadr[jy]])
    assert np.all(others == 0.0)
    assert added[model.jnt_dofadr[jy]] > 0.0  # softening: the remainder opposes the linear spring


def test_ball_joint_gets_the_same_torque_as_a_hinge_pair() -> None:
    import mujoco

    from continuum_sim.model.arm import build_single_arm_model
    from continuum_sim.plant.flexure import flexure_effect

    geometry = ArmGeometry()
    torques = {}
    for joint in ("hinge_pair", "ball"):
        options = ModelOptions(joint=joint, tendons=False, flexure_model="nonlinear")
        root = build_single_arm_model(geometry, options, gravity=False)
        model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
        data = mujoco.MjData(model)
        angle = math.radians(7.3)  # off the grid, 40° off the x axis
        axis = np.array([math.cos(0.7), math.sin(0.7), 0.0])
        if joint == "ball":
            jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "arm/joint_12")
            data.qpos[model.jnt_qposadr[jid]:model.jnt_qposadr[jid] + 4] = [math.cos(angle / 2), *(math.sin(angle / 2) * axis)]
            dofs = [model.jnt_dofadr[jid], model.jnt_dofadr[jid] + 1]
        else:
            ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"arm/joint_12_{a}") for a in "xy"]
            data.qpos[[model.jnt_qposadr[j] for j in ids]] = angle * axis[:2]
            dofs = [model.jnt_dofadr[j] for j in ids]
        effect = flexure_effect(model, ("arm",), geometry, geometry, 1.0)
        torques[joint] = effect.torques(data.qpos, model.nv)[dofs]
    np.testing.assert_allclose(torques["ball"], torques["hinge_pair"], rtol=1e-9)
    assert np.all(np.abs(torques["ball"]) > 1e-3)


def test_flexure_model_option_is_validated() -> None:
    with pytest.raises(ConfigError, match="flexure_model"):
        ModelOptions(flexure_model="cubic")  # type: ignore[arg-type]
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.flexure_observer import flexure_observers

    config = ScenarioConfig.default()
    assert config.model.flexure_model == "nonlinear" and len(flexure_observers(config)) == 1
    rod = ScenarioConfig(arm=ArmGeometry(backbone="rod"), model=config.model)
    assert flexure_observers(rod) == []  # a rod backbone has no leaves


def test_section_stiffness_scale_scales_the_remainder_like_the_springs() -> None:
    import dataclasses

    import mujoco

    from continuum_sim.model.arm import build_single_arm_model
    from continuum_sim.plant.flexure import flexure_effect

    out = {}
    for factor in (1.0, 2.0):
        base = ArmGeometry()
        geometry = dataclasses.replace(base, sections=(dataclasses.replace(base.sections[0], stiffness_scale=factor), *base.sections[1:]))
        options = ModelOptions(joint="hinge_pair", tendons=False, flexure_model="nonlinear")
        root = build_single_arm_model(geometry, options, gravity=False)
        model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "arm/joint_3_y")
        qpos = model.qpos0.copy()
        qpos[model.jnt_qposadr[jid]] = math.radians(5.0)
        tau = flexure_effect(model, ("arm",), geometry, geometry, 1.0).torques(qpos, model.nv)[model.jnt_dofadr[jid]]
        out[factor] = (tau, model.jnt_stiffness[jid])
    assert out[2.0][0] == pytest.approx(2.0 * out[1.0][0], rel=1e-12)
    assert out[2.0][1] == pytest.approx(2.0 * out[1.0][1], rel=1e-12)
