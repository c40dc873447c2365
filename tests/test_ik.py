"""Optimisation IK (SPEC §3): accuracy, modes, bounds, singularity, bad targets, paths."""

import math

import numpy as np
import pytest

from continuum_sim import ArmGeometry, ConfigError, solve_ik
from continuum_sim import kinematics as kin
from continuum_sim.ik import (
    IKOptions,
    IKSolver,
    StepLimits,
    interpolate_q,
    solve_path,
    step_violations,
)
from conftest import random_q

MODES = [("full", "free"), ("full", "planar"), ("axis", "free"), ("axis", "planar")]


def planar_q(rng, geometry, n, plane=0.0):
    """Random configurations bent in one plane: φ ∈ {ψ, ψ + π}."""
    q = random_q(rng, geometry, n)
    q[:, 1::2] = np.where(rng.uniform(size=(n, geometry.n_sections)) < 0.5, plane, plane + np.pi)
    return q


@pytest.mark.parametrize("orientation,phase", MODES)
def test_residual_jacobian_matches_finite_differences(geometry, orientation, phase):
    """The Jacobian the solver uses is the derivative of its residual, near and far from the target."""
    rng = np.random.default_rng(1)
    solver = IKSolver(geometry, orientation, phase, 0.06, plane_angle=0.3)
    for trial in range(12):
        xt = rng.uniform(-0.8, 0.8, solver.n_vars)
        target = kin.forward_kinematics_bending(geometry, np.array(solver.to_w(xt)), tool_length=0.06)
        x = xt + [0.0, 1e-4, 1e-2, 0.3][trial % 4] * rng.normal(size=solver.n_vars)
        tgt = solver._prepare(target)
        _, J, *_ = solver.evaluate(x.tolist(), tgt)
        h = 1e-7
        Jfd = np.zeros_like(J)
        for i in range(solver.n_vars):
            d = np.zeros(solver.n_vars)
            d[i] = h
            rp = np.array(solver.evaluate((x + d).tolist(), tgt, False)[0])
            rm = np.array(solver.evaluate((x - d).tolist(), tgt, False)[0])
            Jfd[:, i] = (rp - rm) / (2 * h)
        np.testing.assert_allclose(J, Jfd, atol=5e-7, rtol=0)


# ------------------------------------------------------------------ accuracy
@pytest.mark.parametrize("orientation,phase", MODES)
@pytest.mark.parametrize("tool", ["none", "grinder"])
def test_random_reachable_poses_converge_cold(geometry, orientation, phase, tool):
    """100% success at 1e-9 m / 1e-9 rad from a cold start on FK poses of random configurations."""
    rng = np.random.default_rng({"none": 11, "grinder": 12}[tool] + 10 * MODES.index((orientation, phase)))
    qs = planar_q(rng, geometry, 40) if phase == "planar" else random_q(rng, geometry, 40)
    targets = kin.tool_centre_pose(geometry, qs, tool)
    for target in targets:
        res = solve_ik(geometry, target, orientation, phase, tool=tool)
        assert res.success, res.message
        assert res.position_error <= 1e-9 and res.orientation_error <= 1e-9
        # The reported errors are the truth: recompute them from q.
        achieved = kin.tool_centre_pose(geometry, res.q, tool)
        assert np.linalg.norm(achieved[:3, 3] - target[:3, 3]) <= 1e-9
        if orientation == "full":
            assert np.linalg.norm(kin.log_so3(achieved[:3, :3].T @ target[:3, :3])) <= 1e-9
        else:
            a, b = achieved[:3, 2], target[:3, 2]
            assert math.atan2(np.linalg.norm(np.cross(a, b)), a @ b) <= 1e-9
        assert np.all(res.q[0::2] >= 0.0) and np.all(res.q[0::2] <= geometry.max_bend + 1e-12)
        if phase == "planar":
            np.testing.assert_allclose(np.cos(res.q[1::2]) ** 2, 1.0, atol=1e-15)  # φ ∈ {0, π}


def test_warm_start_and_determinism(geometry):
    rng = np.random.default_rng(5)
    q_true = random_q(rng, geometry)
    target = kin.forward_kinematics(geometry, q_true)
    a = solve_ik(geometry, target)
    b = solve_ik(geometry, target)
    np.testing.assert_array_equal(a.q, b.q)
    assert a.iterations == b.iterations
    warm = solve_ik(geometry, target, q0=q_true + 0.01)
    assert warm.success and warm.iterations <= 6 and "warm" in warm.message
    np.testing.assert_allclose(kin.to_bending(warm.q), kin.to_bending(q_true), atol=1e-8)


def test_weights_and_tolerances_are_parameters(geometry):
    rng = np.random.default_rng(6)
    target = kin.forward_kinematics(geometry, random_q(rng, geometry))
    loose = IKOptions(position_weight=1.0, orientation_weight=5.0, position_tolerance=1e-4, orientation_tolerance=1e-4)
    res = solve_ik(geometry, target, options=loose)
    assert res.success and res.position_error <= 1e-4
    with pytest.raises(ConfigError, match="position_weight"):
        IKOptions(position_weight=-1.0)
    with pytest.raises(ConfigError, match="n_starts"):
        IKOptions(n_starts=0)


def test_world_frame_targets_with_base(geometry):
    rng = np.random.default_rng(7)
    q = random_q(rng, geometry)
    base = np.eye(4)
    base[:3, 3] = [-0.1, 0.0, 0.0]
    target = kin.tool_centre_pose(geometry, q, "grinder", base=base)
    res = solve_ik(geometry, target, "axis", tool="grinder", base=base)
    assert res.success
    np.testing.assert_allclose(res.pose[:3, 3], target[:3, 3], atol=1e-9)


def test_phase_singularity_straight_sections(geometry):
    """Targets with straight sections (θ = 0, φ undefined) are solved; the straight arm too."""
    for q in (np.zeros(6), np.array([0.0, 0.0, 0.7, 1.0, 0.0, 2.0]), np.array([0.9, -2.0, 0.0, 0.0, 0.4, 0.3])):
        target = kin.forward_kinematics(geometry, q)
        res = solve_ik(geometry, target, q0=np.array([0.3, 0.5, 0.3, -0.5, 0.3, 2.0]))
        assert res.success, (q, res.message)
        np.testing.assert_allclose(res.pose, target, atol=2e-9)
    # Warm start exactly at the singular straight pose, target slightly bent.
    target = kin.forward_kinematics(geometry, np.array([0.05, 0.3, 0.04, -1.0, 0.02, 2.0]))
    res = solve_ik(geometry, target, q0=np.zeros(6), fallback=False)
    assert res.success, res.message


# ------------------------------------------------------------------ failures
def test_unreachable_target_reports_residual(geometry):
    target = np.eye(4)
    target[:3, 3] = [0.0, 0.0, 0.9]  # beyond the 0.54 m arm
    res = solve_ik(geometry, target)
    assert not res.success
    assert res.position_error > 0.3
    assert "outside the workspace" in res.message and "0.5400 m" in res.message
    # Reachable position, impossible orientation: the tip cannot point down next to its base.
    target = np.diag([1.0, -1.0, -1.0, 1.0])
    target[:3, 3] = [0.0, 0.0, 0.5]
    res = solve_ik(geometry, target)
    assert not res.success and "unreachable" in res.message
    assert max(res.position_error, res.orientation_error) > 1e-3


def test_planar_mode_rejects_out_of_plane_target(geometry):
    q = np.array([0.5, 0.7, 0.4, 0.0, 0.3, 0.0])  # section 0 bends out of the x-z plane
    target = kin.forward_kinematics(geometry, q)
    res = solve_ik(geometry, target, "full", "planar")
    assert not res.success and res.position_error > 1e-3
    res_free = solve_ik(geometry, target, "full", "free")
    assert res_free.success


def test_bending_bound_is_respected(geometry):
    """A target that needs more than θmax in a section is refused, not solved out of bounds."""
    big = ArmGeometry.default()
    q = np.array([2.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # 115 deg in one section: beyond 90 deg
    sections = tuple(type(s)(**{**s.__dict__, "max_bend_deg": 150.0}) for s in big.sections)
    wide = ArmGeometry(sections=sections)
    target = kin.forward_kinematics(wide, q)
    res = solve_ik(geometry, target, "full", "planar")
    assert not res.success
    assert np.all(res.q[0::2] <= geometry.max_bend + 1e-12)


@pytest.mark.parametrize(
    "bad,match",
    [
        (np.full((4, 4), np.nan), "NaN"),
        (np.eye(3), r"\(4, 4\)"),
        (np.diag([1.0, 1.0, -1.0, 1.0]), "not a rotation"),
        (np.diag([2.0, 1.0, 1.0, 1.0]), "not a rotation"),
        (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1.0]]), "last row"),
    ],
)
def test_malformed_targets_raise_clear_errors(geometry, bad, match):
    with pytest.raises(ValueError, match=match):
        solve_ik(geometry, bad)


def test_bad_arguments(geometry):
    with pytest.raises(ValueError, match="orientation"):
        solve_ik(geometry, np.eye(4), orientation="roll")
    with pytest.raises(ValueError, match="phase"):
        solve_ik(geometry, np.eye(4), phase="spiral")
    with pytest.raises(ValueError, match="q0"):
        solve_ik(geometry, np.eye(4), q0=[0.0, np.nan, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="q0"):
        solve_ik(geometry, np.eye(4), q0=[0.0, 0.0])
    with pytest.raises(ConfigError, match="tool"):
        solve_ik(geometry, np.eye(4), tool="laser")


# ------------------------------------------------------------------ paths
def _wiggly_path(geometry, n=60, seed=3, planar=False):
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, n)[:, None]
    if planar:
        sa, sb = rng.uniform(-1.2, 1.2, 3), rng.uniform(-1.2, 1.2, 3)
        sig = sa + (sb - sa) * s
        W = np.zeros((n, 6))
        W[:, 0::2] = sig
    else:
        wa, wb = rng.uniform(-0.8, 0.8, 6), rng.uniform(-0.8, 0.8, 6)
        W = wa + (wb - wa) * s + 0.1 * np.sin(2 * np.pi * s * np.array([1, 2, 1, 3, 2, 1]))
    return kin.forward_kinematics_bending(geometry, W, tool_length=0.06), W


@pytest.mark.parametrize("orientation", ["full", "axis"])
def test_path_respects_step_limits_and_unwraps_phase(geometry, orientation):
    targets, W = _wiggly_path(geometry)
    limits = StepLimits(max_dtheta_deg=2.0, max_dphi_deg=10.0)
    sol = solve_path(geometry, targets, kin.from_bending(W[0]), orientation, tool=0.06, limits=limits)
    assert sol.success, sol.message
    assert sol.original.sum() == len(targets)
    assert len(sol.q) > len(targets)  # the coarse path needed bisection to meet 2 deg steps
    assert np.all(sol.position_error <= 1e-9) and np.all(sol.orientation_error <= 1e-9)
    for a, b in zip(sol.q[:-1], sol.q[1:]):
        assert not step_violations(a, b, limits)
    bent = sol.q[:, 0::2] > limits.phase_free_below
    dphi = np.abs(np.diff(sol.q[:, 1::2], axis=0))
    assert np.all(dphi[bent[1:] & bent[:-1]] <= limits.max_dphi + 1e-12)  # unwrapped: no 2π jumps


def test_planar_path_keeps_phase_on_the_plane(geometry):
    targets, W = _wiggly_path(geometry, planar=True)
    sol = solve_path(geometry, targets, kin.from_bending(W[0]), "full", "planar", tool=0.06)
    assert sol.success, sol.message
    phases = sol.q[:, 1::2]
    assert np.all(np.isclose(phases, 0.0, atol=1e-15) | np.isclose(np.abs(phases), np.pi, atol=1e-15))
    # W's signed θ changes sign along the path for at least one section: φ flips there.
    assert np.any(np.diff(np.sign(W[:, 0::2]), axis=0) != 0)


def test_path_with_unreachable_point_names_it(geometry):
    targets, W = _wiggly_path(geometry, n=10)
    targets = targets.copy()
    targets[6, :3, 3] += [0.0, 0.0, 0.5]
    sol = solve_path(geometry, targets, kin.from_bending(W[0]), "full", tool=0.06)
    assert not sol.success and sol.failed_index == 6
    assert "toolpath point 6" in sol.message
    assert len(sol.q) >= 6  # points before the failure are kept


def test_interpolation_eq12_and_near_zero(geometry):
    qa = np.array([0.5, 0.2, 0.8, -3.0, 0.3, 1.0])
    qb = np.array([0.7, 0.4, 0.9, -3.3, 0.5, 1.2])  # unwrapped φ beyond -π on section 1
    f = np.linspace(0, 1, 5)
    q = interpolate_q(qa, qb, f)
    np.testing.assert_allclose(q[0], qa)
    np.testing.assert_allclose(q[-1], qb)
    np.testing.assert_allclose(q[2], 0.5 * (qa + qb))  # eq. 12: linear in θ and φ
    # A section passing near θ = 0 interpolates straight through in bending coordinates.
    qa = np.array([0.01, 0.0, 0.5, 0.0, 0.5, 0.0])
    qb = np.array([0.01, np.pi, 0.5, 0.0, 0.5, 0.0])
    mid = interpolate_q(qa, qb, [0.5])[0]
    assert mid[0] < 1e-12
    # Planar: φ stays exactly 0 or π.
    qa = np.array([0.02, 0.0, 0.5, np.pi, 0.5, 0.0])
    qb = np.array([0.03, np.pi, 0.5, np.pi, 0.5, 0.0])
    q = interpolate_q(qa, qb, np.linspace(0, 1, 11), phase="planar")
    assert set(np.round(q[:, 1], 12)) <= {0.0, round(np.pi, 12)}
    w = kin.to_bending(q)[:, 0]
    np.testing.assert_allclose(np.diff(w), np.diff(w)[0], atol=1e-15)  # linear in signed θ
