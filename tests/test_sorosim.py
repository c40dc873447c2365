"""The backbone as a uniform rod against SoRoSim Cosserat-rod statics (SPEC §10).

A seeded subset of the 500 load cases per rod keeps this fast; the full table over link
counts and joint kinds comes from ``scripts/sorosim_table.py`` (README).
"""

import dataclasses
import math

import numpy as np
import pytest

from continuum_sim.configio import ConfigError
from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model.rod import RodSpec, apply_node_wrench, compile_rod, node_body_ids, node_poses
from continuum_sim.validation.sorosim import RODS, STEEL, TPU, RodStatics, load_statics, subset
from continuum_sim.validation.statics import StaticSolver, StaticSolverOptions

choose_gl_backend()
import mujoco  # noqa: E402

SUBSET = 25


@pytest.fixture(scope="module", params=list(RODS))
def rod_cases(request):
    rod = RODS[request.param]
    return rod, load_statics(rod)


def test_reading_of_the_statics_files(rod_cases):
    """500 cases; gravity is g in every case; stations run from the clamp (origin) to s = L
    with chords as long as their arcs (to the data's 0.1 mm rounding); the Euler angles read as intrinsic X-Y-Z turn
    +x onto the chord directions, and read as extrinsic x-y-z they do not."""
    from scipy.spatial.transform import Rotation

    rod, cases = rod_cases
    assert len(cases) == 500
    assert np.allclose([np.linalg.norm(c.gravity) for c in cases], 9.81, atol=0.01)
    worst = {"XYZ": 0.0, "xyz": 0.0}
    for c in cases[:50]:
        assert np.allclose(c.positions[0], 0.0) and c.arclength[-1] == pytest.approx(rod.length)
        ds = np.diff(c.arclength)
        keep = ds > 0
        chords = np.diff(c.positions, axis=0)[keep]
        length = np.linalg.norm(chords, axis=1)
        assert np.all((length > 0.97 * ds[keep]) & (length < ds[keep] + 2e-4)), "stations are not at those arc lengths"
        mid_euler = 0.5 * (c.euler[1:] + c.euler[:-1])[keep]
        for sequence in worst:
            first_axis = Rotation.from_euler(sequence, mid_euler).as_matrix()[:, :, 0]
            worst[sequence] = max(worst[sequence], np.abs(first_axis - chords / length[:, None]).max())
    assert worst["XYZ"] < 0.02
    assert worst["xyz"] > 0.1


def test_tip_errors_on_a_subset(rod_cases):
    """25 seeded cases, 20 links, ball joint + series twist hinge (``ball_twist``): mean tip
    error ≤ 0.5 % of L (OpenCR-MuJoCo reports < 1 %), worst tip ≤ 1 %, worst station
    ≤ 1 %. The steel rod's tip cross-section also turns like the reference (mean ≤ 0.5°),
    which checks the twist stiffness GJ; the TPU reference behaves as twist-rigid (its
    cross-sections do not twist at all: see README), so its frame is not compared."""
    rod, cases = rod_cases
    statics = RodStatics(rod.spec(20))
    errors = [statics.error(c) for c in subset(cases, SUBSET, seed=1)]
    assert all(e.converged for e in errors)
    tip = np.array([e.tip for e in errors]) / rod.length
    assert tip.mean() <= 0.005
    assert tip.max() <= 0.01
    assert max(e.shape for e in errors) <= 0.01 * rod.length
    if rod is STEEL:
        assert np.degrees(np.mean([e.tip_angle for e in errors])) <= 0.5


def test_swapped_wrench_reading_misses(rod_cases):
    """Reading force from the Eul rows and moment from the P rows (the README's wrong way)
    lands the tip far off: the comparison can tell the two readings apart."""
    rod, cases = rod_cases
    statics = RodStatics(rod.spec(10, "ball"))
    misses = []
    for c in cases[:3]:
        swapped = dataclasses.replace(c, mid_wrench=np.roll(c.mid_wrench, 3), tip_wrench=np.roll(c.tip_wrench, 3))
        misses.append(statics.error(swapped).tip / rod.length)
    assert min(misses) > 0.05


def test_static_solver_agrees_with_damped_simulation():
    """The equilibrium the root finder returns is where a heavily damped simulation of the
    same loaded rod comes to rest (TPU rod, 10 links, a SoRoSim case)."""
    case = load_statics(TPU)[0]
    spec = TPU.spec(10, "ball")
    statics = RodStatics(spec)
    positions, _, converged, _ = statics.solve(case)
    assert converged

    damped = RodSpec(spec.length, spec.radius, spec.youngs_modulus, spec.poisson_ratio, spec.density, 10, "ball", damping=0.02, timestep=5e-4)
    model = compile_rod(damped)
    data = mujoco.MjData(model)
    ids = node_body_ids(model, 10)
    model.opt.gravity[:] = case.gravity
    apply_node_wrench(model, data, ids[5], case.mid_wrench[:3], case.mid_wrench[3:])
    apply_node_wrench(model, data, ids[-1], case.tip_wrench[:3], case.tip_wrench[3:])
    for _ in range(8000):
        mujoco.mj_step(model, data)
    assert np.abs(data.qvel).max() < 1e-3, "not at rest"
    settled, _ = node_poses(data, ids)
    assert np.linalg.norm(settled[-1] - positions[-1]) < 1e-4 * spec.length


def test_static_solver_handles_ball_joints_from_a_bent_start():
    """Ball-joint quaternions are solved in the tangent space: from a bent start pose the
    solver finds the same equilibrium as from the straight one."""
    spec = RodSpec(0.4, 5e-3, 70e6, 0.4, 1200.0, n_links=8, joint="ball")
    model = compile_rod(spec)
    data = mujoco.MjData(model)
    wrenches = np.zeros((model.nbody, 6))
    wrenches[-1] = [0.0, 0.1, -0.2, 0.01, 0.0, 0.0]
    solver = StaticSolver(model, data)
    data.qpos[:] = model.qpos0
    assert solver.solve(np.zeros(3), wrenches).converged
    straight_start = data.xpos[-1].copy()
    data.qpos[:] = model.qpos0
    data.qpos[0:4] = [math.cos(0.2), 0.0, math.sin(0.2), 0.0]
    assert solver.solve(np.zeros(3), wrenches).converged
    np.testing.assert_allclose(data.xpos[-1], straight_start, atol=1e-9)


@pytest.mark.parametrize(
    ("field", "kwargs"),
    [
        ("radius", dict(radius=0.5)),
        ("n_links", dict(n_links=0)),
        ("joint", dict(joint="free")),
        ("poisson_ratio", dict(poisson_ratio=0.0)),
        ("density", dict(density=-1.0)),
    ],
)
def test_rod_spec_rejects_nonsense(field, kwargs):
    base = dict(length=0.6, radius=0.8e-3, youngs_modulus=200e9, poisson_ratio=0.33, density=7870.0)
    with pytest.raises(ConfigError) as info:
        RodSpec(**{**base, **kwargs})
    assert info.value.field == field


@pytest.mark.parametrize(("field", "kwargs"), [("tolerance", dict(tolerance=0.0)), ("ramps", dict(ramps=(1, 0)))])
def test_solver_options_reject_nonsense(field, kwargs):
    with pytest.raises(ConfigError) as info:
        StaticSolverOptions(**kwargs)
    assert info.value.field == field


def test_mid_wrench_needs_an_even_link_count():
    with pytest.raises(ConfigError, match="n_links"):
        RodStatics(STEEL.spec(11))
