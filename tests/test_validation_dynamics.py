"""The capsule rod against SoRoSim release dynamics (validation/sorosim/sorosim_dynamics).

Quick subset: release case 1 of each rod (the full 10 cases per rod: `continuum-sim
validate --only sorosim.dynamics.steel sorosim.dynamics.tpu`, docs/validation.md).
"""

import numpy as np
import pytest

from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model.rod import (
    RodSpec,
    apply_node_wrench,
    compile_rod,
    node_body_ids,
)
from continuum_sim.validation.sorosim import RODS, STEEL, TPU
from continuum_sim.validation.sorosim_dynamics import (
    CASES,
    compare_release,
    load_release,
    swing,
)
from continuum_sim.validation.statics import StaticSolver

choose_gl_backend()
import mujoco  # noqa: E402


def _held_tip(rod, case, swap: bool) -> np.ndarray:
    spec = RodSpec(rod.length, rod.radius, rod.youngs_modulus, rod.poisson_ratio, rod.density, 20, "ball_twist")
    model = compile_rod(spec)
    data = mujoco.MjData(model)
    nodes = node_body_ids(model, 20)
    for body, w in ((nodes[10], case.mid_wrench), (nodes[-1], case.tip_wrench)):
        force, moment = (w[3:], w[:3]) if swap else (w[:3], w[3:])
        apply_node_wrench(model, data, body, force, moment)
    assert StaticSolver(model, data).solve(case.gravity, data.xfrc_applied.copy()).converged
    return data.xpos[nodes[-1]].copy()


@pytest.mark.parametrize("rod", [STEEL, TPU], ids=lambda r: r.name)
def test_reading_of_the_dynamics_files(rod):
    """10 cases per rod, 2001 samples every 5 ms from t = 0, |g| = 9.81, damping in the
    files' range; the holding wrenches read moment-then-force put the held rod's tip on the
    record's first sample (< 1.5 mm), read force-then-moment they miss it by > 5 cm."""
    for k in CASES:
        case = load_release(rod, k)
        assert len(case.time) == 2001 and case.time[0] == 0.0
        assert np.allclose(np.diff(case.time), 0.005, atol=1e-9)
        assert np.linalg.norm(case.gravity) == pytest.approx(9.81, abs=0.01)
        assert 1e-3 < case.damping < 1e-2
    case = load_release(rod, 1)
    assert np.linalg.norm(_held_tip(rod, case, swap=False) - case.tip[0]) < 1.5e-3
    assert np.linalg.norm(_held_tip(rod, case, swap=True) - case.tip[0]) > 0.05


def test_swing_measure_on_a_known_damped_oscillation():
    """Frequency and decay of x = A e^(−σt) cos(2πft) + ripple, recovered within 0.5 %."""
    t = np.arange(0, 10, 0.005)
    f, sigma = 3.1, 0.8
    x = 0.2 * np.exp(-sigma * t) * np.cos(2 * np.pi * f * t) + 0.002 * np.sin(2 * np.pi * 19.0 * t) * np.exp(-3 * t)
    tip = np.column_stack([0.6 + 0.1 * x, x, 0.3 * x])
    s = swing(t, tip)
    assert s.frequency == pytest.approx(f, rel=5e-3)
    assert s.decay_rate == pytest.approx(sigma, rel=5e-3)


@pytest.mark.parametrize("rod_name", list(RODS))
def test_release_case_1_matches_sorosim(rod_name):
    """Tip RMS over the 10 s record ≤ 1 % of L, first swing frequency within 2 %, decay
    rate within 10 %, with joint damping c = τ·k from the file's τ (no fitted constant)."""
    result, _, _ = compare_release(RODS[rod_name], 1)
    assert result.tip_rms_pct <= 1.0
    assert abs(result.frequency_error_pct) <= 2.0
    assert abs(result.decay_error_pct) <= 10.0
