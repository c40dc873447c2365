"""The Cosserat tendon model (validation/cosserat.py) against its own analytic limits.

Independent closed forms only: a single tendon without gravity bends a circular arc of
κ = τ·r/EI at any tension (Rucker & Webster's limit, checked to 0.1 % — it holds to the
solver's tolerance); small tip-force and own-weight deflections are Euler–Bernoulli's;
lumped masses deflect like the superposed point-load formula.
"""

import math

import numpy as np
import pytest

from continuum_sim.configio import ConfigError
from continuum_sim.validation.cosserat import (
    CosseratRobot,
    CosseratSolver,
    RodPiece,
    Tendon,
    constant_curvature_tip,
)

EI, L, R = 0.05, 0.2, 0.015


@pytest.mark.parametrize(("tension", "phi"), [(0.01, 0.0), (1.0, 0.7), (20.0, 2.5)])
def test_single_tendon_bends_a_constant_curvature_arc(tension, phi):
    """κ = τ·r/EI within 0.1 % at every station; the tip lies on that arc, bent toward the tendon."""
    robot = CosseratRobot((RodPiece(L, EI, EI, EI / 1.3, 0.0),), (Tendon((R * math.cos(phi), R * math.sin(phi)), L, tension),))
    sol = CosseratSolver(robot).solve()
    kappa = tension * R / EI
    k = np.linalg.norm(sol.curvatures[:, :2], axis=1)
    assert sol.converged
    assert np.abs(k / kappa - 1.0).max() < 1e-3
    assert np.abs(sol.curvatures[:, 2]).max() < 1e-9 * max(kappa, 1.0)  # no twist
    assert np.linalg.norm(sol.tip - constant_curvature_tip(kappa, L, phi)) < 1e-3 * L


def test_opposed_equal_tendons_cancel_and_unequal_ones_bend_by_the_difference():
    pieces = (RodPiece(L, EI, EI, EI, 0.0),)
    even = CosseratSolver(CosseratRobot(pieces, (Tendon((R, 0.0), L, 5.0), Tendon((-R, 0.0), L, 5.0)))).solve()
    assert np.linalg.norm(even.tip - [0, 0, L]) < 1e-9
    odd = CosseratSolver(CosseratRobot(pieces, (Tendon((R, 0.0), L, 7.0), Tendon((-R, 0.0), L, 5.0)))).solve()
    assert np.linalg.norm(odd.tip - constant_curvature_tip(2.0 * R / EI, L)) < 1e-6 * L


def test_small_tip_force_and_own_weight_match_euler_bernoulli():
    force = 1e-4 * EI / L**2
    tip = CosseratSolver(CosseratRobot((RodPiece(L, EI, EI, EI, 0.0),), (), tip_force=(force, 0, 0))).solve().tip
    assert tip[0] == pytest.approx(force * L**3 / (3 * EI), rel=1e-3)
    mu, g = 0.05, 1e-4 * EI / (0.05 * L**3)
    tip = CosseratSolver(CosseratRobot((RodPiece(L, EI, EI, EI, mu),), (), gravity=(g, 0, 0))).solve().tip
    assert tip[0] == pytest.approx(mu * g * L**4 / (8 * EI), rel=1e-3)


def test_lumped_masses_deflect_like_superposed_point_loads():
    """Masses at s_i (including one at the tip, on a break shared with the piece end):
    δ = Σ m g s²(3L − s)/(6EI). Each mass must act once (a float-duplicated break once
    applied the tip mass twice)."""
    n = 10
    masses = tuple((i * L / n, 0.002) for i in range(1, n + 1))
    g = 0.05
    robot = CosseratRobot((RodPiece(L, EI, EI, EI, 0.0),), (), gravity=(g, 0, 0), point_masses=masses)
    tip = CosseratSolver(robot).solve().tip
    expected = sum(m * g * s**2 * (3 * L - s) / (6 * EI) for s, m in masses)
    assert tip[0] == pytest.approx(expected, rel=1e-3)


def test_a_tendon_ending_mid_rod_leaves_the_distal_part_straight():
    """Termination at L/2: the distal half carries no moment, so it stays straight, tangent to the arc."""
    robot = CosseratRobot((RodPiece(L / 2, EI, EI, EI, 0.0), RodPiece(L / 2, EI, EI, EI, 0.0)), (Tendon((R, 0.0), L / 2, 2.0),))
    sol = CosseratSolver(robot).solve()
    kappa = 2.0 * R / EI
    mid = constant_curvature_tip(kappa, L / 2)
    theta = kappa * L / 2
    expected = mid + L / 2 * np.array([math.sin(theta), 0.0, math.cos(theta)])
    assert np.linalg.norm(sol.tip - expected) < 1e-6 * L


def test_bad_inputs_name_the_field():
    with pytest.raises(ConfigError, match="tension"):
        Tendon((R, 0.0), L, -1.0)
    with pytest.raises(ConfigError, match="length"):
        RodPiece(0.0, EI, EI, EI, 0.0)
    with pytest.raises(ConfigError, match="twist"):
        RodPiece(L, EI, EI, 0.0, 0.0)
