"""Segment stiffness: the analytic model (model.stiffness) against an independent 3-D frame FE model.

The FE model (validation.fe_segment) is checked first against textbook beam results;
then the analytic bend (x, y) and twist stiffness must agree with it within 10 % over
the three sections, leaves on the axis, at the default placement and far off it, an
uneven leaf layout, and both central joints.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from continuum_sim.configio import ConfigError
from continuum_sim.geometry import ArmGeometry
from continuum_sim.model.stiffness import (
    flexure_segment_stiffness_matrix,
    joint_stiffnesses,
    segment_stiffness,
)
from continuum_sim.validation.fe_segment import (
    LeafSection,
    cantilever_chain,
    rectangle_torsion_constant,
    section_fe_stiffness,
)

GEOMETRY = ArmGeometry()
LEAF = LeafSection(
    width=0.006, thickness=0.001, youngs_modulus=2.0e9, poisson_ratio=0.38
)


# ------------------------------------------------------------------ FE vs textbook
def test_fe_cantilever_tip_load_matches_euler_bernoulli_plus_shear():
    """Tip force P on a slender cantilever: δ = PL³/3EI + PL/κGA (Timoshenko), both principal planes."""
    length, load = 0.2, 0.01
    for axis, inertia in ((0, LEAF.i_tangential_axis), (1, LEAF.i_radial_axis)):
        wrench = np.zeros(6)
        wrench[axis] = load
        tip = cantilever_chain(length, LEAF, 10, wrench)
        expected = load * length**3 / (3.0 * LEAF.youngs_modulus * inertia)
        shear = (
            load * length / (LEAF.shear_coefficient * LEAF.shear_modulus * LEAF.area)
        )
        assert tip[axis] == pytest.approx(expected + shear, rel=1e-9)
        assert tip[axis] == pytest.approx(
            expected, rel=1e-3
        )  # slender: shear is negligible
        # end rotation PL²/2EI (shear adds none)
        assert abs(tip[4 - axis]) == pytest.approx(
            load * length**2 / (2.0 * LEAF.youngs_modulus * inertia), rel=1e-9
        )


def test_fe_torsion_bar_and_axial_bar():
    length = 0.1
    tip = cantilever_chain(length, LEAF, 4, np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.01]))
    assert tip[5] == pytest.approx(
        0.01 * length / (LEAF.shear_modulus * LEAF.torsion_constant), rel=1e-12
    )
    tip = cantilever_chain(length, LEAF, 4, np.array([0.0, 0.0, 5.0, 0.0, 0.0, 0.0]))
    assert tip[2] == pytest.approx(
        5.0 * length / (LEAF.youngs_modulus * LEAF.area), rel=1e-12
    )


@pytest.mark.parametrize(
    "ratio, beta",
    [(1.0, 0.141), (2.0, 0.229), (3.0, 0.263), (5.0, 0.291), (10.0, 0.312)],
)
def test_rectangle_torsion_constant_matches_the_textbook_table(ratio, beta):
    """J = β·b·t³ for a b×t rectangle (Timoshenko & Goodier's table, 3 significant figures)."""
    assert rectangle_torsion_constant(ratio, 1.0) / ratio == pytest.approx(
        beta, abs=5e-4
    )  # ± half the last digit


# ------------------------------------------------------------------ analytic vs FE
def _fe_for(geometry: ArmGeometry, index: int) -> np.ndarray:
    return section_fe_stiffness(geometry, geometry.sections[index])

def _with_leaves(
    radius: float | None, angles=(0.0, 120.0, 240.0), joint: str = "ball"
) -> ArmGeometry:
    sections = tuple(
        dataclasses.replace(
            s,
            leaf_radius=s.leaf_radius if radius is None else radius,
            leaf_angles_deg=angles,
        )
        for s in GEOMETRY.sections
    )
    return dataclasses.replace(GEOMETRY, sections=sections, central_joint=joint)


CASES = {
    "default": _with_leaves(None),
    "on_axis": _with_leaves(0.0),
    "off_axis_8mm": _with_leaves(0.008),
    "at_cable_radius": _with_leaves(0.015),
    "uneven_angles": _with_leaves(0.004, angles=(0.0, 100.0, 230.0)),
}


@pytest.mark.parametrize("section", [0, 1, 2])
@pytest.mark.parametrize("case", list(CASES))
def test_segment_stiffness_matches_fe_ball_joint(case, section):
    geometry = CASES[case]
    fe = _fe_for(geometry, section)
    analytic = flexure_segment_stiffness_matrix(geometry, geometry.sections[section])
    kx, ky, kz = segment_stiffness(geometry, geometry.sections[section])
    for name, value, ref in (
        ("bend x", kx, fe[0, 0]),
        ("bend y", ky, fe[1, 1]),
        ("twist", kz, fe[2, 2]),
    ):
        assert value == pytest.approx(ref, rel=0.10), (
            f"{case} section {section} {name}: {value:.4g} vs FE {ref:.4g}"
        )
    # the whole matrix, couplings included (bend–bend coupling of an uneven layout)
    scale = np.abs(fe).max()
    assert np.allclose(analytic, fe, rtol=0.0, atol=0.10 * scale)


@pytest.mark.parametrize("section", [0, 2])
def test_universal_joint_blocks_twist_and_keeps_bending(section):
    geometry = _with_leaves(0.004, joint="universal")
    fe = _fe_for(geometry, section)  # 2×2: x, y
    kx, ky, kz = segment_stiffness(geometry, geometry.sections[section])
    assert math.isinf(kz)
    assert kx == pytest.approx(fe[0, 0], rel=0.10) and ky == pytest.approx(
        fe[1, 1], rel=0.10
    )


def test_leaves_off_the_axis_stretch():
    """The stretching term: stiffness grows ~ r² once leaves stand off the joint centre."""
    on = segment_stiffness(CASES["on_axis"], CASES["on_axis"].sections[0])[0]
    far = segment_stiffness(
        CASES["at_cable_radius"], CASES["at_cable_radius"].sections[0]
    )[0]
    assert far / on > 50.0


def test_rod_backbone_stiffness_is_ei_and_gj_over_pitch():
    geometry = dataclasses.replace(GEOMETRY, backbone="rod")
    rod = geometry.rod
    for k, section in enumerate(geometry.sections):
        kx, ky, kz = segment_stiffness(geometry, section)
        ei = rod.youngs_modulus * math.pi * rod.radius**4 / 4.0
        gj = (
            rod.youngs_modulus
            / (2 * (1 + rod.poisson_ratio))
            * math.pi
            * rod.radius**4
            / 2.0
        )
        assert kx == ky == pytest.approx(ei / section.pitch)
        assert kz == pytest.approx(gj / section.pitch)
        # resampling keeps the section's rigidity: k_joint·L/n = EI
        k_joint = joint_stiffnesses(geometry, k, 25)[0]
        assert k_joint * section.length / 25 == pytest.approx(ei)


def test_bad_leaf_and_rod_fields_name_the_field():
    with pytest.raises(ConfigError, match="leaf_radius"):
        _with_leaves(0.03)
    with pytest.raises(ConfigError, match="leaf_free_length"):
        dataclasses.replace(
            GEOMETRY,
            sections=(
                dataclasses.replace(GEOMETRY.sections[0], leaf_free_length=0.05),
            ),
        )
    with pytest.raises(ConfigError, match="backbone"):
        dataclasses.replace(GEOMETRY, backbone="spring")
    with pytest.raises(ConfigError, match="rod.radius"):
        dataclasses.replace(
            GEOMETRY,
            backbone="rod",
            rod=dataclasses.replace(GEOMETRY.rod, radius=0.021),
        )
