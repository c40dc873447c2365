"""An arm section, as the arm builder makes it, against cantilever beam theory (SPEC §10).

Each section is built alone (tendons and gravity off), clamped at its base plate, and
loaded at its last disk through ``xfrc_applied``; static shapes come from the static
solver, frequencies from the linearised model and from a free-vibration run. The beam's
EI is the flexure formula's ``section_bending_rigidity``; a model whose joint stiffness,
its scaling with the segment count, or MuJoCo's joint springs disagreed with it fails.
"""

import math

import numpy as np
import pytest

from continuum_sim import ArmGeometry, disk_frames
from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model.options import ModelOptions, model_geometry
from continuum_sim.model.rod import RodSpec, compile_rod
from continuum_sim.validation import beam
from continuum_sim.validation.section import build_section_cantilever, single_section_geometry
from continuum_sim.validation.statics import StaticSolver, linear_natural_frequencies

choose_gl_backend()
import mujoco  # noqa: E402

GEOMETRY = ArmGeometry.default()
SECTIONS = range(GEOMETRY.n_sections)


def solve_tip_load(section: int, options: ModelOptions, force=(0, 0, 0), torque=(0, 0, 0)):
    """Disk centres (n+1, 3) and tip rotation of a loaded section cantilever, and its beam."""
    model, section_beam = build_section_cantilever(GEOMETRY, section, options)
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "arm/base")]
    ids += [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"arm/disk_{i}") for i in range(1, section_beam.n + 1)]
    wrenches = np.zeros((model.nbody, 6))
    wrenches[ids[-1]] = np.concatenate([force, torque])
    result = StaticSolver(model, data).solve(np.zeros(3), wrenches)
    assert result.converged
    return data.xpos[ids].copy(), data.xmat[ids[-1]].reshape(3, 3).copy(), section_beam


@pytest.mark.parametrize("segments", [0, 20])
@pytest.mark.parametrize("section", SECTIONS)
def test_small_tip_force_deflects_like_euler_bernoulli(section, segments):
    """δ = F·L³/(3EI) and tip slope F·L²/(2EI) within 1 %; and the chain's exact discrete
    value F·L³/(3EI)·(1 − 1/(4n²)) (joints sample the bending moment by the midpoint rule)
    within 0.05 %, which separates the O(1/n²) discretisation from any stiffness error."""
    options = ModelOptions(segments_per_section=segments)
    _, _, b = solve_tip_load(section, options)
    force = 1e-3 * b.ei / b.length**2  # δ/L ≈ 3e-4: linear regime
    nodes, tip_rotation, b = solve_tip_load(section, options, force=(force, 0, 0))
    deflection = nodes[-1, 0]
    assert deflection == pytest.approx(beam.tip_deflection_force(force, b.length, b.ei), rel=0.01)
    assert deflection == pytest.approx(beam.chain_tip_deflection(force, b.length, b.ei, b.n), rel=5e-4)
    slope = math.atan2(tip_rotation[0, 2], tip_rotation[2, 2])
    assert slope == pytest.approx(beam.tip_slope_force(force, b.length, b.ei), rel=0.01)


@pytest.mark.parametrize("joint", ["ball", "hinge_pair"])
@pytest.mark.parametrize("section", SECTIONS)
def test_small_tip_moment_matches_euler_bernoulli(section, joint):
    """δ = M·L²/(2EI) and tip slope M·L/EI within 1 % (exact for the chain: uniform curvature)."""
    options = ModelOptions(joint=joint)
    _, _, b = solve_tip_load(section, options)
    moment = 1e-3 * b.ei / b.length
    nodes, tip_rotation, _ = solve_tip_load(section, options, torque=(0, moment, 0))
    assert nodes[-1, 0] == pytest.approx(beam.tip_deflection_moment(moment, b.length, b.ei), rel=0.01)
    slope = math.atan2(tip_rotation[0, 2], tip_rotation[2, 2])
    assert slope == pytest.approx(beam.arc_angle(moment, b.length, b.ei), rel=0.01)


@pytest.mark.parametrize(
    ("joint", "axis_deg", "segments"),
    [("ball", 0, 0), ("ball", 130, 0), ("ball", 0, 4), ("ball", 250, 20), ("hinge_pair", 0, 0), ("hinge_pair", 90, 0)],
)
@pytest.mark.parametrize("section", SECTIONS)
def test_large_tip_moment_bends_a_circular_arc(section, joint, axis_deg, segments):
    """A 90° end moment (the section's bending limit): the elastica is a circular arc of
    angle M·L/EI. Tip angle within 1 %. Disk centres: on the discrete PCC shape of that
    angle (SPEC §2 kinematics, the chain's exact answer to a uniform moment) within
    1e-6·L, and, for ≥ 10 disks, within 1 % of L from the continuous arc (the chain's
    nodes sit on a circle of radius R·(1 − (θ/n)²/12): 1.3 % short with 4 disks)."""
    options = ModelOptions(joint=joint, segments_per_section=segments)
    _, _, b = solve_tip_load(section, options)
    angle = math.pi / 2.0
    moment = angle * b.ei / b.length
    phi = math.radians(axis_deg)
    axis = np.array([-math.sin(phi), math.cos(phi), 0.0])  # bends +z toward (cos φ, sin φ, 0)
    nodes, tip_rotation, _ = solve_tip_load(section, options, torque=moment * axis)

    tip_angle = math.acos(np.clip(tip_rotation[2, 2], -1.0, 1.0))
    assert tip_angle == pytest.approx(beam.arc_angle(moment, b.length, b.ei), rel=0.01)
    pcc_geometry = model_geometry(single_section_geometry(GEOMETRY, section), options)
    pcc = disk_frames(pcc_geometry, [beam.arc_angle(moment, b.length, b.ei), phi])[:, :3, 3]
    assert np.linalg.norm(nodes - pcc, axis=1).max() < 1e-6 * b.length
    if b.n >= 10:
        arc = beam.arc_point(moment, b.ei, np.arange(b.n + 1) * b.pitch)  # (along, across)
        expected = arc[:, :1] * [0.0, 0.0, 1.0] + arc[:, 1:] * [math.cos(phi), math.sin(phi), 0.0]
        assert np.linalg.norm(nodes - expected, axis=1).max() < 0.01 * b.length


@pytest.mark.parametrize("segments", [0, 20])
@pytest.mark.parametrize("section", SECTIONS)
def test_first_bending_frequency_of_linearised_model(section, segments):
    """Smallest ω of K v = ω² M v at the straight pose (K by finite differences of the
    model's generalised force, M = mj_fullM), undamped, armature off, within 1 % of the
    continuous beam the disk chain discretises (``SectionBeam.first_frequency``: disks'
    rotary inertia and the tip disk's outer half included; the plain β₁² value is ~10 %
    higher and is not the right reference for 10 disks)."""
    options = ModelOptions(segments_per_section=segments, joint_damping=0.0, joint_armature=0.0)
    model, b = build_section_cantilever(GEOMETRY, section, options)
    data = mujoco.MjData(model)
    frequency = linear_natural_frequencies(model, data, 2)
    assert frequency[0] == pytest.approx(frequency[1], rel=1e-6), "bending should be isotropic"
    assert frequency[0] == pytest.approx(b.first_frequency(), rel=0.01)


def zero_crossing_frequency(t: np.ndarray, x: np.ndarray) -> float:
    """Frequency (Hz) from the mean spacing of linearly interpolated zero crossings."""
    sign = np.signbit(x)
    k = np.flatnonzero(sign[1:] != sign[:-1])
    crossings = t[k] - x[k] * (t[k + 1] - t[k]) / (x[k + 1] - x[k])
    return (len(crossings) - 1) / (2.0 * (crossings[-1] - crossings[0]))


def test_free_vibration_frequency_of_section():
    """The proximal section as the robot uses it (10 disks, default armature, implicitfast at
    0.5 ms), damping off, released from a static tip deflection: the tip's zero crossings
    over ~6 periods give the first frequency within 3 % of the beam reference."""
    options = ModelOptions(joint_damping=0.0, timestep=5e-4)
    model, b = build_section_cantilever(GEOMETRY, 0, options)
    data = mujoco.MjData(model)
    tip = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"arm/disk_{b.n}")
    wrenches = np.zeros((model.nbody, 6))
    wrenches[tip, 0] = 0.02 * b.ei / b.length**2
    assert StaticSolver(model, data).solve(np.zeros(3), wrenches).converged
    data.xfrc_applied[:] = 0.0
    reference = b.first_frequency()
    steps = int(6.0 / reference / model.opt.timestep)
    t, x = np.empty(steps), np.empty(steps)
    for k in range(steps):
        mujoco.mj_step(model, data)
        t[k], x[k] = data.time, data.xpos[tip, 0]
    assert zero_crossing_frequency(t, x) == pytest.approx(reference, rel=0.03)


def test_thin_rod_frequency_matches_the_plain_formula():
    """A thin steel rod (r/L ≈ 1e-3: rotary inertia negligible, tip node carrying half a link's
    mass) with 40 links: first frequency within 1 % of 1.875104²·sqrt(EI/(ρA L⁴))/(2π)."""
    spec = RodSpec(0.6, 0.8e-3, 200e9, 0.33, 7870.0, n_links=40, joint="ball")
    model = compile_rod(spec)
    frequency = linear_natural_frequencies(model, mujoco.MjData(model), 1)[0]
    expected = beam.BETA1**2 * math.sqrt(spec.bending_rigidity / (spec.mass_per_length * spec.length**4)) / (2 * math.pi)
    assert frequency == pytest.approx(expected, rel=0.01)
    assert beam.cantilever_first_frequency(spec.bending_rigidity, spec.mass_per_length, spec.length) == pytest.approx(expected)


@pytest.mark.parametrize(
    ("mass_ratio", "beta"), [(0.1, 1.7227), (0.2, 1.6164), (1.0, 1.2479), (100.0, (3.0 / 100.2357) ** 0.25)]
)
def test_tip_mass_frequency_matches_published_roots(mass_ratio, beta):
    """The beam reference itself: first roots β of the cantilever-with-tip-mass equation
    1 + cos β cosh β + (M_t/μL)·β(cos β sinh β − sin β cosh β) = 0 (tabulated, e.g. Blevins),
    and for a heavy tip the spring–mass limit ω² = 3EI/(L³(M_t + 0.2357 μL))."""
    f = beam.cantilever_first_frequency(1.0, 1.0, 1.0, tip_mass=mass_ratio)
    assert math.sqrt(2 * math.pi * f) == pytest.approx(beta, abs=2e-4)


def test_rotary_inertia_lowers_frequency_like_rayleigh():
    """Small rotary inertia r per length: Rayleigh's quotient with the Euler–Bernoulli mode
    φ gives ω²/ω₀² ≈ 1 − r·∫φ'²/∫μφ² (∫φ'²/∫φ² = 4.64/L² for mode 1, by quadrature here)."""
    b1 = beam.BETA1
    sigma = (math.cosh(b1) + math.cos(b1)) / (math.sinh(b1) + math.sin(b1))
    x = np.linspace(0.0, 1.0, 20001)
    phi = np.cosh(b1 * x) - np.cos(b1 * x) - sigma * (np.sinh(b1 * x) - np.sin(b1 * x))
    dphi = np.gradient(phi, x)
    ratio = np.trapezoid(dphi**2, x) / np.trapezoid(phi**2, x)
    r = 1e-4
    f0 = beam.cantilever_first_frequency(1.0, 1.0, 1.0)
    f = beam.cantilever_first_frequency(1.0, 1.0, 1.0, rotary_inertia_per_length=r)
    assert (f / f0) ** 2 == pytest.approx(1.0 - r * ratio, abs=1e-6)
