"""The compiled kinematics and control tick against independent references within stated tolerances.

References: the vectorised numpy formulation in ``kinematics_oracle`` (segment sums, SO(3)
left Jacobian), central finite differences of ``kinematics.forward_kinematics_bending``,
``kinematics.log_so3``, and the control law written with numpy (``reference_update``).
"""

import kinematics_oracle as oracle
import numpy as np
import pytest
from conftest import random_q
from scipy.spatial.transform import Rotation

from continuum_sim import kinematics as kin
from continuum_sim.control import ControlConfig
from continuum_sim.control.arm import ArmController
from continuum_sim.control.kernels import plan_sample, rotation_error
from continuum_sim.kinematics_kernels import ArmPose, cable_model, model_cable_lengths


def _samples(rng: np.random.Generator, geometry) -> list[np.ndarray]:
    """Random shapes plus the straight arm and shapes at the Taylor-series switch points (1e-4, 1e-2 rad)."""
    return [kin.to_bending(q) for q in random_q(rng, geometry, 30)] + [
        np.zeros(6),
        np.array([1e-9, 0.0, 0.0, -1e-9, 3e-5, 0.0]),
        np.array([1e-3, 2e-3, 0.005, 0.0, 0.0, 0.02]),
        np.array([5e-5, 5e-5, 0.0099, 0.0, 1e-2, 1e-4]),
    ]


@pytest.mark.parametrize("tool", [0.0, 0.06])
def test_pose_jacobian_matches_the_vectorised_oracle(geometry, tool):
    """Closed form (kernel) vs segment sums (oracle): the same pose and Jacobian to 1e-13 (m, rad; |J| ~ 0.5)."""
    pose = ArmPose(geometry, tool)
    for w in _samples(np.random.default_rng(1), geometry):
        R, p, J = pose.pose_jacobian(w)
        T, J0 = oracle.jacobian_bending(geometry, w, tool)
        np.testing.assert_allclose(np.reshape(R, (3, 3)), T[:3, :3], rtol=0, atol=1e-13)
        np.testing.assert_allclose(p, T[:3, 3], rtol=0, atol=1e-13)
        np.testing.assert_allclose(np.reshape(J, (6, 6)), J0, rtol=1e-10, atol=1e-13)
        R2, p2, none = pose.pose_jacobian(w, derivatives=False)
        assert none is None and R2 == R and p2 == p


def test_pose_jacobian_matches_finite_differences_of_the_forward_kinematics(geometry):
    """Against central differences (h = 1e-6) of ``forward_kinematics_bending``: truncation ~1e-12, rounding ~1e-10."""
    pose = ArmPose(geometry, 0.06)
    h = 1e-6
    for w in _samples(np.random.default_rng(2), geometry)[-14:]:
        _, _, J = pose.pose_jacobian(w)
        Jn = np.empty((6, 6))
        for c in range(6):
            dw = np.zeros(6)
            dw[c] = h
            Tp = kin.forward_kinematics_bending(geometry, w + dw, tool_length=0.06)
            Tm = kin.forward_kinematics_bending(geometry, w - dw, tool_length=0.06)
            Jn[:3, c] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
            Jn[3:, c] = kin.log_so3(Tp[:3, :3] @ Tm[:3, :3].T) / (2 * h)
        np.testing.assert_allclose(np.reshape(J, (6, 6)), Jn, rtol=0, atol=1e-8)


def test_cable_lengths_match_the_vectorised_oracle(geometry):
    model, out = cable_model(geometry), np.empty(9)
    for w in _samples(np.random.default_rng(3), geometry):
        model_cable_lengths(model, w, out)
        np.testing.assert_allclose(out, oracle.cable_lengths_bending(geometry, w), rtol=0, atol=1e-15)
    np.testing.assert_allclose(kin.cable_lengths_bending(geometry, np.zeros(6)), kin.straight_cable_lengths(geometry), atol=1e-15)


def test_rotation_error_is_the_log_of_the_relative_rotation():
    rng = np.random.default_rng(2)
    r = np.empty(3)
    for scale in (1e-9, 1e-3, 0.5, 2.0, 2.95, 3.1):
        Ra = kin.exp_so3(rng.normal(size=3))
        Rt = kin.exp_so3(scale * rng.normal(size=3) / np.sqrt(3)) @ Ra
        expected = kin.log_so3(Rt @ Ra.T)
        if rotation_error(Rt, Ra, r):
            np.testing.assert_allclose(r, expected, atol=1e-9)
        else:  # beyond 3 rad the caller takes log_so3
            assert np.linalg.norm(expected) > 3.0


def _rotation(rng: np.random.Generator, scale: float) -> np.ndarray:
    return Rotation.from_rotvec(rng.normal(0.0, scale, 3)).as_matrix()


def reference_update(c: dict, law: ArmController, q, tcp_plan, pos, mat, dt, holding, tensions) -> np.ndarray:
    """The control law with numpy and the oracle kinematics, on the state ``c`` (updated in place)."""
    cfg, geometry = law.config, law.geometry

    def commanded() -> np.ndarray:
        w = kin.to_bending(q) + c["correction"] + c["proportional"]
        theta = np.hypot(w[0::2], w[1::2])
        scale = np.minimum(1.0, geometry.max_bend / np.maximum(theta, 1e-300))
        return w * np.repeat(scale, 2)

    if holding:
        if not c["holding"]:
            c["correction"] = c["correction"] + c["proportional"]
            c["proportional"] = np.zeros_like(c["proportional"])
        dt = 0.0
    c["holding"] = holding
    if cfg.mode == "closed" and dt > 0.0:
        w = commanded()
        Rt = law.base[:3, :3].T  # world -> arm base frame, where the Jacobian lives
        weights = np.array([1.0, 1.0, 1.0] + [cfg.orientation_weight] * 3)
        error = np.concatenate([Rt @ (tcp_plan[:3, 3] - pos), Rt @ kin.log_so3(tcp_plan[:3, :3] @ mat.T)]) * weights
        J = oracle.jacobian_bending(geometry, w, law.tool_length)[1] * weights[:, None]
        if law.roll_free:  # angular rows about the measured tool x and y axes only
            select = np.zeros((5, 6))
            select[:3, :3] = np.eye(3)
            select[3:, 3:] = (Rt @ mat[:, :2]).T
            error, J = select @ error, select @ J
        step = J.T @ np.linalg.solve(J @ J.T + cfg.damping * np.eye(len(error)), error)
        correction = c["correction"] + (cfg.outer_gain * dt * step if law.gain is None else dt * law.gain @ step)
        norms = np.hypot(correction[0::2], correction[1::2])
        factor = np.where(norms > law.max_correction, law.max_correction / np.maximum(norms, 1e-300), 1.0)
        c["correction"], c["proportional"] = correction * np.repeat(factor, 2), cfg.outer_proportional * step
        if tensions is not None and cfg.min_tension > 0.0:
            slackest = tensions.reshape(-1, 3).min(axis=1)
            extra = c["extra"] + cfg.tension_gain * (cfg.min_tension - slackest) / law.cable_kp * dt
            c["extra"] = np.clip(extra, 0.0, cfg.max_extra_tension / law.cable_kp)
    return oracle.cable_lengths_bending(geometry, commanded()) - law.offset - c["extra"][kin.cable_sections(geometry)]


@pytest.mark.parametrize("roll_free", [False, True])
@pytest.mark.parametrize("gain", [False, True])
@pytest.mark.parametrize("mode", ["closed", "open"])
def test_compiled_tick_follows_the_numpy_law(geometry, roll_free, gain, mode):
    """Set-points and state over 60 ticks (holding, > 3 rad rotation errors, bounds hit): within 1e-12 (m, rad)."""
    rng = np.random.default_rng(4)
    base = np.eye(4)
    base[:3, :3] = _rotation(rng, 0.5)
    base[:3, 3] = rng.normal(0.0, 0.1, 3)
    matrix = rng.normal(0.0, 2.0, (6, 6)) if gain else None
    config = ControlConfig(mode=mode, max_correction_deg=3.0)  # a small bound, so it acts
    controller = ArmController(geometry, config, base, 0.06, 3.0e4, roll_free=roll_free, gain=matrix)
    state = {"correction": np.zeros(6), "proportional": np.zeros(6), "extra": np.zeros(3), "holding": False}
    bound_hit = False
    for tick in range(60):
        q = random_q(rng, geometry)
        tcp = kin.forward_kinematics_bending(geometry, kin.to_bending(q), base, 0.06)
        pos = tcp[:3, 3] + rng.normal(0.0, 0.01, 3)
        mat = tcp[:3, :3] @ _rotation(rng, 2.5 if tick % 5 == 3 else 0.2)  # now and then beyond 3 rad
        tensions = rng.uniform(0.0, 10.0, 9)
        holding, dt = tick % 20 > 15, 0.0 if tick == 0 else 0.008
        got = controller.update(q, tcp, pos, mat, dt, holding, tensions)
        expected = reference_update(state, controller, q, tcp, pos, mat, dt, holding, tensions)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12, err_msg=f"tick {tick}")
        for name in ("correction", "proportional", "extra"):
            np.testing.assert_allclose(getattr(controller, name), state[name], rtol=0, atol=1e-12, err_msg=f"{tick} {name}")
        bound_hit |= not holding and np.hypot(state["correction"][0::2], state["correction"][1::2]).max() > np.radians(3.0) - 1e-12
    assert bound_hit == (mode == "closed")


def test_plan_interpolation_is_linear_and_clamped():
    """``controllers.plan_at``'s kernel: (1 - f)·a + f·b at the sample index and fraction, clamped at both ends."""
    rng = np.random.default_rng(5)
    times = 0.25 + 0.01 * np.arange(500)
    q, tcp = rng.normal(size=(500, 6)), rng.normal(size=(500, 4, 4))
    for t in list(rng.uniform(0.0, 5.5, 100)) + [0.0, 0.25, 0.26, float(times[-1]), 9.0]:
        x = np.clip((t - times[0]) / (times[1] - times[0]), 0.0, len(times) - 1.0)
        q1, tcp1 = plan_sample(times, t, q, tcp)
        np.testing.assert_allclose(q1, [np.interp(x, np.arange(500), q[:, j]) for j in range(6)], rtol=0, atol=1e-13)
        np.testing.assert_allclose(tcp1[1, 2], np.interp(x, np.arange(500), tcp[:, 1, 2]), rtol=0, atol=1e-13)
