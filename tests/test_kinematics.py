"""Discrete PCC kinematics (SPEC §2) against closed forms, limits and finite differences."""

import dataclasses

import numpy as np
import pytest

from continuum_sim import (
    ArmGeometry,
    SectionGeometry,
    cable_lengths,
    continuous_forward_kinematics,
    disk_frames,
    forward_kinematics,
    jacobian,
    straight_cable_lengths,
    tool_centre_pose,
)
from continuum_sim import kinematics as kin
from conftest import random_q


def test_straight_arm_tip_and_cables(geometry):
    tip = forward_kinematics(geometry, np.zeros(6))
    np.testing.assert_allclose(tip[:3, 3], [0.0, 0.0, 0.540], atol=1e-15)
    np.testing.assert_allclose(tip[:3, :3], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(cable_lengths(geometry, np.zeros(6)), straight_cable_lengths(geometry), atol=1e-15)
    np.testing.assert_allclose(straight_cable_lengths(geometry), [0.21] * 3 + [0.39] * 3 + [0.54] * 3, atol=1e-15)


@pytest.mark.parametrize("phi", np.linspace(-np.pi, np.pi, 13))
def test_zero_bend_is_independent_of_phase(geometry, phi):
    q = np.array([0.0, phi, 0.0, -phi, 0.0, 2 * phi])
    np.testing.assert_allclose(forward_kinematics(geometry, q), forward_kinematics(geometry, np.zeros(6)), atol=1e-15)
    J = jacobian(geometry, q)
    assert np.all(np.isfinite(J))
    np.testing.assert_allclose(J[:, 1::2], 0.0, atol=1e-15)  # phase has no effect at θ = 0
    # Bending straight out of θ = 0 along φ moves the tip toward the direction φ.
    direction = J[:3, 4]
    assert direction[0] * np.cos(2 * phi) + direction[1] * np.sin(2 * phi) > 0.0


def test_matches_spec_segment_product(geometry):
    """The closed-form sum equals SPEC §2's T_seg^n product literally built from Rz/Ry."""

    def rz(a):
        c, s = np.cos(a), np.sin(a)
        return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])

    def ry(a):
        c, s = np.cos(a), np.sin(a)
        return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])

    def trans_z(d):
        T = np.eye(4)
        T[2, 3] = d
        return T

    q = np.array([0.7, 0.4, 1.2, -2.0, 0.3, 3.0])
    T = np.eye(4)
    for k, s in enumerate(geometry.sections):
        th, ph = q[2 * k], q[2 * k + 1]
        seg = trans_z(s.pitch / 2) @ rz(ph) @ ry(th / s.n_segments) @ rz(-ph) @ trans_z(s.pitch / 2)
        T = T @ np.linalg.matrix_power(seg, s.n_segments)
    np.testing.assert_allclose(forward_kinematics(geometry, q), T, atol=1e-14)
    np.testing.assert_allclose(disk_frames(geometry, q)[-1], T, atol=1e-14)


def test_positive_theta_with_zero_phase_bends_toward_plus_x(geometry):
    tip = forward_kinematics(geometry, np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0]))
    assert tip[0, 3] > 0.05 and abs(tip[1, 3]) < 1e-15


def test_converges_to_continuous_arc_at_second_order():
    """Tip error of the discrete model vs the arc falls as 1/n² (measured rate ≈ 2)."""
    q = np.array([1.2, 0.3, 0.8, -1.1, 1.5, 2.2])
    errors = []
    counts = [5, 10, 20, 40, 80]
    for n in counts:
        geom = dataclasses.replace(
            ArmGeometry.default(),
            disk_thickness=0.001,
            sections=tuple(dataclasses.replace(s, n_segments=n) for s in ArmGeometry.default().sections),
        )
        diff = forward_kinematics(geom, q)[:3, 3] - continuous_forward_kinematics(geom, q)[:3, 3]
        errors.append(np.linalg.norm(diff))
    rate = -np.polyfit(np.log(counts), np.log(errors), 1)[0]
    assert 1.9 < rate < 2.1, f"convergence rate {rate:.3f}, errors {errors}"
    assert errors[-1] < 2e-5


def test_single_section_continuous_arc_closed_form():
    section = SectionGeometry(0.2, 0.04, 0.004, 0.001, n_segments=10)
    geom = ArmGeometry(sections=(section,))
    theta, phi = 1.0, 0.6
    T = continuous_forward_kinematics(geom, np.array([theta, phi]))
    x = 0.2 * (1 - np.cos(theta)) / theta
    z = 0.2 * np.sin(theta) / theta
    np.testing.assert_allclose(T[:3, 3], [x * np.cos(phi), x * np.sin(phi), z], atol=1e-15)


@pytest.mark.parametrize("section_index", [0, 1, 2])
def test_small_bend_cable_change_matches_linear_law(geometry, section_index):
    """Δl ≈ -r θ cos(α - φ) for each cable passing a slightly bent section."""
    theta, phi = 1e-4, 0.7
    q = np.zeros(6)
    q[2 * section_index] = theta
    q[2 * section_index + 1] = phi
    delta = cable_lengths(geometry, q) - straight_cable_lengths(geometry)
    angles = np.concatenate([s.cable_angles for s in geometry.sections])
    expected = -geometry.cable_hole_radius * theta * np.cos(angles - phi)
    expected[: 3 * section_index] = 0.0  # cables ending before this section do not see it
    np.testing.assert_allclose(delta, expected, atol=1e-10, rtol=0)


def test_cable_lengths_bent_section_exact_formula(geometry):
    """Each segment of a section bent by θ: |l| = 2 (p/2 - r cos(α-φ) sin(θ/2n))... exactly."""
    q = np.array([1.0, 0.5, 0.0, 0.0, 0.0, 0.0])
    s = geometry.sections[0]
    beta = 1.0 / s.n_segments
    d = geometry.cable_hole_radius * np.cos(s.cable_angles - 0.5)
    # Two half-pitch arms meeting at the joint, each tilted by β/2 from the chord.
    expected = s.n_segments * 2.0 * (s.pitch / 2 * np.cos(beta / 2) - d * np.sin(beta / 2))
    np.testing.assert_allclose(cable_lengths(geometry, q)[:3], expected, atol=1e-14)


def _fd_jacobian(f, x, h=1e-6):
    T0 = f(x)
    J = np.zeros((6, x.size))
    for i in range(x.size):
        dx = np.zeros_like(x)
        dx[i] = h
        Tp, Tm = f(x + dx), f(x - dx)
        J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        J[3:, i] = kin.log_so3(Tp[:3, :3] @ Tm[:3, :3].T) / (2 * h)
    assert T0.shape == (4, 4)
    return J


@pytest.mark.parametrize("tool", ["none", "grinder", "gripper"])
def test_jacobian_matches_finite_differences(geometry, tool):
    rng = np.random.default_rng(1)
    length = geometry.tools.length(tool)
    for q in random_q(rng, geometry, 20):
        J = jacobian(geometry, q, tool_length=length)
        Jfd = _fd_jacobian(lambda x: tool_centre_pose(geometry, x, tool), q)
        np.testing.assert_allclose(J, Jfd, atol=1e-7, rtol=0)


def test_bending_jacobian_matches_finite_differences_through_zero(geometry):
    """The compiled Jacobian (``jacobian_bending``) against the forward kinematics' central differences, mount included."""
    rng = np.random.default_rng(2)
    samples = [np.zeros(6), np.array([1e-9, 0.0, 0.0, 1e-9, -1e-9, 0.0])] + list(rng.normal(0, 0.6, (10, 6)))
    base = kin.forward_kinematics(geometry, [0.3, 0.2, 0.1, -1.0, 0.2, 2.0])  # any rigid transform
    T, J = kin.jacobian_bending(geometry, np.array(samples), base, tool_length=0.06)  # batched
    for i, w in enumerate(samples):
        Jfd = _fd_jacobian(lambda x: kin.forward_kinematics_bending(geometry, x, base, tool_length=0.06), w)
        np.testing.assert_allclose(J[i], Jfd, atol=1e-7, rtol=0)
        np.testing.assert_allclose(T[i], kin.forward_kinematics_bending(geometry, w, base, tool_length=0.06), atol=1e-15)


def test_batched_calls_equal_single_calls(geometry):
    rng = np.random.default_rng(3)
    qs = random_q(rng, geometry, 7)
    batch = forward_kinematics(geometry, qs)
    cables = cable_lengths(geometry, qs)
    for i, q in enumerate(qs):
        np.testing.assert_allclose(batch[i], forward_kinematics(geometry, q), atol=1e-15)
        np.testing.assert_allclose(cables[i], cable_lengths(geometry, q), atol=1e-15)


def test_bending_coordinates_round_trip(geometry):
    rng = np.random.default_rng(4)
    q = random_q(rng, geometry, 50)
    back = kin.from_bending(kin.to_bending(q))
    np.testing.assert_allclose(back[:, 0::2], q[:, 0::2], atol=1e-14)
    np.testing.assert_allclose(np.cos(back[:, 1::2] - q[:, 1::2]), 1.0, atol=1e-12)


def test_so3_log_exp_round_trip_including_pi():
    rng = np.random.default_rng(5)
    axes = rng.normal(size=(40, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([rng.uniform(0, np.pi, 36), [0.0, 1e-9, np.pi - 1e-7, np.pi]])
    w = axes * angles[:, None]
    R = kin.exp_so3(w)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-14)
    np.testing.assert_allclose(kin.exp_so3(kin.log_so3(R)), R, atol=1e-9)


def test_wrong_q_length_is_rejected(geometry):
    with pytest.raises(ValueError, match="q must have 6 entries"):
        forward_kinematics(geometry, np.zeros(5))


def test_cable_lengths_equal_the_vectorised_oracle(geometry):
    """The compiled cable lengths (one closed form per section) against the per-hole numpy oracle, to 1e-15 m."""
    import kinematics_oracle as oracle

    rng = np.random.default_rng(7)
    w = kin.to_bending(np.concatenate([random_q(rng, geometry, 20), np.zeros((1, 6))]))
    np.testing.assert_allclose(kin.cable_lengths_bending(geometry, w), oracle.cable_lengths_bending(geometry, w), atol=1e-15, rtol=0)
