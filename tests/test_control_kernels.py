"""The numba control tick (``control_kernels``) gives the Python path's numbers bit for bit."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from continuum_sim import kinematics as kin
from continuum_sim.control import ArmController, ControlConfig
from continuum_sim.control_kernels import kernels
from conftest import random_q


def _samples(rng: np.random.Generator, geometry) -> list[np.ndarray]:
    return [kin.to_bending(q) for q in random_q(rng, geometry, 40)] + [
        np.zeros(6),
        np.array([1e-9, 0.0, 0.0, -1e-9, 3e-5, 0.0]),
        np.array([1e-3, 2e-3, 0.005, 0.0, 0.0, 0.02]),
        np.array([5e-5, 5e-5, 0.0099, 0.0, 1e-2, 1e-4]),
    ]


def test_hypot_is_pythons():
    hypot = kernels()["hypot"]
    rng = np.random.default_rng(0)
    values = rng.normal(size=(20000, 2)) * 10.0 ** rng.integers(-12, 4, (20000, 1))
    special = [(0.0, 0.0), (-0.0, 3.0), (1e-310, 2e-311), (5e-324, 0.0), (math.inf, 1.0), (1.0, -math.inf), (3.0, 4.0)]
    for a, b in list(values) + special:
        assert hypot(a, b) == math.hypot(a, b), (a, b)
    assert math.isnan(hypot(math.nan, 1.0))


@pytest.mark.parametrize("tool", [0.0, 0.06])
def test_pose_jacobian_kernel_is_the_arm_kernel(geometry, tool):
    kernel = kin.ArmKernel(geometry, tool)
    pose_jacobian = kernels()["pose_jacobian"]
    lengths = np.array([L for L, _ in kernel._sections])
    segments = np.array([n for _, n in kernel._sections])
    R, p, J = np.empty(9), np.empty(3), np.empty(36)
    for w in _samples(np.random.default_rng(1), geometry):
        pose_jacobian(lengths, segments, tool, w, R, p, J)
        R0, p0, J0 = kernel.pose_jacobian(w)
        assert R.tolist() == R0 and p.tolist() == p0 and J.tolist() == J0


def test_pose_jacobian_kernel_matches_finite_differences(geometry):
    kernel = kin.ArmKernel(geometry, 0.06)
    pose_jacobian = kernels()["pose_jacobian"]
    lengths = np.array([L for L, _ in kernel._sections])
    segments = np.array([n for _, n in kernel._sections])
    R, p, J = np.empty(9), np.empty(3), np.empty(36)
    R1, p1, R2, p2, scratch = np.empty(9), np.empty(3), np.empty(9), np.empty(3), np.empty(36)
    h = 1e-6
    for w in _samples(np.random.default_rng(2), geometry)[:20]:
        pose_jacobian(lengths, segments, 0.06, w, R, p, J)
        Jn = np.empty((6, 6))
        for c in range(6):
            dw = np.zeros(6)
            dw[c] = h
            pose_jacobian(lengths, segments, 0.06, w + dw, R1, p1, scratch)
            pose_jacobian(lengths, segments, 0.06, w - dw, R2, p2, scratch)
            Jn[:3, c] = (p1 - p2) / (2 * h)
            dR = (R1.reshape(3, 3) - R2.reshape(3, 3)) / (2 * h) @ R.reshape(3, 3).T  # [ω]×
            Jn[3:, c] = [dR[2, 1], dR[0, 2], dR[1, 0]]
        np.testing.assert_allclose(J.reshape(6, 6), Jn, atol=1e-7)


def test_cable_kernel_is_the_cable_kernel(geometry):
    cables = kin.CableKernel(geometry)
    cable_lengths = kernels()["cable_lengths"]
    segments = np.array([n for n, _ in cables._sections])
    halves = np.array([h for _, h in cables._sections])
    out = np.empty(9)
    for w in _samples(np.random.default_rng(3), geometry):
        cable_lengths(w, segments, halves, cables._pair_section, cables._pair_holes, cables._gather, out)
        assert np.array_equal(out, cables.lengths(w))


def _rotation(rng: np.random.Generator, scale: float) -> np.ndarray:
    return Rotation.from_rotvec(rng.normal(0.0, scale, 3)).as_matrix()


@pytest.mark.parametrize("roll_free", [False, True])
@pytest.mark.parametrize("gain", [False, True])
@pytest.mark.parametrize("mode", ["closed", "open"])
def test_compiled_tick_equals_the_python_tick(geometry, roll_free, gain, mode):
    """Set-points, commands and the controller state after every tick, including holding and > 3 rad errors."""
    rng = np.random.default_rng(4)
    base = np.eye(4)
    base[:3, :3] = _rotation(rng, 0.5)
    base[:3, 3] = rng.normal(0.0, 0.1, 3)
    matrix = rng.normal(0.0, 2.0, (6, 6)) if gain else None
    config = ControlConfig(mode=mode, max_correction_deg=3.0)  # a small bound, so it acts
    compiled = ArmController(geometry, config, base, 0.06, 3.0e4, roll_free=roll_free, gain=matrix)
    python = ArmController(geometry, config, base, 0.06, 3.0e4, roll_free=roll_free, gain=matrix)
    python.compiled = False
    for tick in range(150):
        q = random_q(rng, geometry)
        tcp = kin.forward_kinematics_bending(geometry, kin.to_bending(q), base, 0.06)
        pos = tcp[:3, 3] + rng.normal(0.0, 0.01, 3)
        mat = tcp[:3, :3] @ _rotation(rng, 2.5 if tick % 5 == 3 else 0.2)  # now and then beyond 3 rad
        tensions = rng.uniform(0.0, 10.0, 9)
        holding, dt = tick % 40 > 35, 0.0 if tick == 0 else 0.008
        a = compiled.update(q, tcp, pos, mat, dt, holding, tensions)
        b = python.update(q, tcp, pos, mat, dt, holding, tensions)
        assert np.array_equal(a, b), tick
        assert compiled.last_command == python.last_command
        for name in ("correction", "proportional", "extra"):
            assert np.array_equal(getattr(compiled, name), getattr(python, name)), (tick, name)


def test_plan_interpolation_kernel_is_numpys():
    """``controllers.plan_at``'s kernel: numpy's (1 - f)·a + f·b at the same index and fraction, clamped at both ends."""
    rng = np.random.default_rng(5)
    times = 0.25 + 0.01 * np.arange(500)
    q, tcp = rng.normal(size=(500, 6)), rng.normal(size=(500, 4, 4))
    plan_at = kernels()["plan_at"]
    for t in list(rng.uniform(0.0, 5.5, 300)) + [0.0, 0.25, 0.26, float(times[-1]), 9.0]:
        x = min(max((t - float(times[0])) / float(times[1] - times[0]), 0.0), len(times) - 1.0)
        i0 = min(int(x), len(times) - 2)
        f = x - i0
        q1, tcp1 = plan_at(times, t, q, tcp)
        assert np.array_equal(q1, (1.0 - f) * q[i0] + f * q[i0 + 1])
        assert np.array_equal(tcp1, (1.0 - f) * tcp[i0] + f * tcp[i0 + 1])


def test_solve_is_scipys_dposv():
    """The kernel's dposv (by address) returns scipy.linalg.lapack.dposv's solution and info, bit for bit."""
    from scipy.linalg.lapack import dposv

    from continuum_sim.control_kernels import dposv_address

    solve = kernels()["solve_spd"]
    address, uplo, ints = dposv_address(), np.array([ord("U")], dtype=np.uint8), np.zeros(5, dtype=np.int32)
    rng = np.random.default_rng(6)
    for trial in range(2000):
        m = 5 + trial % 2
        J = rng.normal(size=(m, 6)) * 10.0 ** rng.uniform(-3.0, 0.0, (m, 1))
        A = J @ J.T + (1e-4 if trial % 7 else 0.0) * np.eye(m)
        if trial % 100 == 0:
            A = -A  # not positive definite: info > 0
        b = rng.normal(size=m)
        _, x0, info0 = dposv(A, b)
        x = b.copy()
        info = solve(address, uplo, ints, A, np.empty((m, m)), x)
        assert info == info0
        if info == 0:
            assert np.array_equal(x, x0)
