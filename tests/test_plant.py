"""The transmission (docs/plant.md): elastic cables EA/L and the motors' encoder loops.

References are independent of the model's code: the rope's E·A from its diameter and
modulus by hand, the routed length from SPEC §2's straight cable lengths plus the lead,
and the motor tests on a one-slider rig where the load is a known weight.
"""

import math

import numpy as np
import pytest

from continuum_sim.geometry import ArmGeometry
from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model.arm import build_single_arm_model
from continuum_sim.model.options import ModelOptions
from continuum_sim.plant.drive import MotorBank, MotorRatings, arm_motor_bank

choose_gl_backend()
import mujoco  # noqa: E402


def _compile(root):
    return mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())


def test_each_cable_stretches_by_tension_times_l_over_ea():
    """Gravity off, straight arm, every cable held at a motor position 1 mm short of taut:
    the settled tension over the measured stretch (tendon length − motor position) is
    E·π d²/4 / (lead + in-arm length) within 1 %, and distal cables are softer."""
    geometry = ArmGeometry()
    options = ModelOptions(joint="hinge_pair", timestep=0.002, cable_model="elastic")
    model = _compile(build_single_arm_model(geometry, options, gravity=False))
    data = mujoco.MjData(model)
    cables = np.arange(model.nu)
    bank = arm_motor_bank(model, cables, cables, options)
    mujoco.mj_forward(model, data)
    set_points = data.ten_length.copy() - 1.0e-3
    bank.reset(data, set_points)
    for _ in range(300):  # 1.2 s at 125 Hz
        bank.command(data, set_points, 0.008)
        mujoco.mj_step(model, data, nstep=4)
    mujoco.mj_forward(model, data)
    tension = -data.actuator_force
    stretch = data.ten_length - bank.position
    assert np.all(tension > 5.0)
    ea = options.rope_modulus * math.pi * options.rope_diameter**2 / 4.0  # by hand
    in_arm = np.repeat(np.cumsum([s.length for s in geometry.sections]), 3)  # SPEC §2 straight lengths
    expected = ea / (options.cable_lead_length + in_arm)
    np.testing.assert_allclose(tension / stretch, expected, rtol=0.01)
    assert expected[0] > expected[3] > expected[6]


def _slider_rig(load_kg: float, stiffness: float, max_force: float):
    """A mass on a vertical slider hanging from one cable (a fixed tendon on the slide)."""
    xml = f"""
    <mujoco>
      <option timestep="0.002" integrator="implicitfast"/>
      <worldbody>
        <body name="load" pos="0 0 0">
          <joint name="slide" type="slide" axis="0 0 1" damping="20"/>
          <geom type="box" size="0.01 0.01 0.01" mass="{load_kg}"/>
        </body>
      </worldbody>
      <tendon><fixed name="cable"><joint joint="slide" coef="-1"/></fixed></tendon>
      <actuator>
        <position name="cable" tendon="cable" kp="{stiffness}" forcelimited="true"
                  forcerange="{-max_force} 0" ctrllimited="false"/>
      </actuator>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    return model, mujoco.MjData(model)


def _run(bank, model, data, set_point, seconds, dt=0.008):
    positions = []
    for _ in range(round(seconds / dt)):
        bank.command(data, np.array([set_point]), dt)
        mujoco.mj_step(model, data, nstep=round(dt / model.opt.timestep))
        positions.append(bank.position[0])
    return np.array(positions)


@pytest.mark.parametrize("ki", [400.0, 0.0])
def test_motor_holds_its_set_point_under_a_static_load(ki):
    """A 2 kg weight (19.6 N) on the cable: the PI loop ends within 1 µm of its set-point;
    without the integral term the DC motor's load droop leaves a steady error."""
    ratings = MotorRatings(max_speed=0.06, max_force=150.0, kp=40.0, ki=ki)
    model, data = _slider_rig(2.0, 1.0e5, 150.0)
    bank = MotorBank(model, [0], [0], ratings)
    mujoco.mj_forward(model, data)
    set_point = data.ten_length[0] - 0.2e-3  # taut
    bank.reset(data, [set_point])
    _run(bank, model, data, set_point, 4.0)
    tension = -data.actuator_force[0]
    assert tension == pytest.approx(2.0 * 9.81, rel=0.02)
    error = abs(bank.position[0] - set_point)
    if ki > 0:
        assert error <= 1e-6
    else:
        droop = ratings.max_speed / ratings.max_force
        assert error == pytest.approx(droop * tension / ratings.kp, rel=0.05)  # the DC motor's load line


def test_motor_respects_its_speed_limit():
    ratings = MotorRatings(max_speed=0.02, max_force=150.0, kp=40.0, ki=400.0)
    model, data = _slider_rig(0.5, 1.0e5, 150.0)
    bank = MotorBank(model, [0], [0], ratings)
    mujoco.mj_forward(model, data)
    start = data.ten_length[0] - 0.1e-3
    bank.reset(data, [start])
    positions = _run(bank, model, data, start + 0.05, 4.0)  # a 50 mm step out
    speeds = np.abs(np.diff(np.concatenate([[start], positions]))) / 0.008
    assert speeds.max() <= ratings.max_speed * (1 + 1e-9)
    assert speeds.max() >= 0.95 * ratings.max_speed  # it does run at the limit
    assert positions[-1] == pytest.approx(start + 0.05, abs=1e-6)  # and still arrives


def test_motor_stalls_at_its_force_limit():
    """Reeling in against a weight heavier than the rating: the tension never exceeds the
    rating and the motor stops pulling (it stalls, the weight stays down)."""
    ratings = MotorRatings(max_speed=0.05, max_force=10.0, kp=40.0, ki=400.0)
    model, data = _slider_rig(2.0, 1.0e5, ratings.max_force)  # 19.6 N weight
    bank = MotorBank(model, [0], [0], ratings)
    mujoco.mj_forward(model, data)
    bank.reset(data, [data.ten_length[0]])
    tensions, heights = [], []
    for _ in range(250):
        bank.command(data, np.array([data.ten_length[0] - 0.05]), 0.008)  # always 50 mm more to reel in
        mujoco.mj_step(model, data, nstep=4)
        tensions.append(-data.actuator_force[0])
        heights.append(data.qpos[0])
    assert max(tensions) <= ratings.max_force * (1 + 1e-9)
    assert heights[-1] < 0.0  # the weight was not lifted


@pytest.mark.parametrize("implicit", [False, True])
def test_lumped_model_passes_set_points_through(implicit):
    """Lumped servo: the set-point is the actuator's control; with the linearly implicit
    spring it leads by one physics step of its rate (the spring's end-of-step anchor)."""
    geometry = ArmGeometry()
    options = ModelOptions(cable_model="lumped", cable_implicit_spring=implicit)
    model = _compile(build_single_arm_model(geometry, options, gravity=False))
    np.testing.assert_allclose(model.actuator_gainprm[:, 0], options.cable_kp)
    np.testing.assert_allclose(-model.actuator_biasprm[:, 2], options.cable_kp * options.timestep if implicit else 0.0)
    data = mujoco.MjData(model)
    bank = arm_motor_bank(model, np.arange(9), np.arange(9), options)
    bank.command(data, np.full(9, 0.3), 0.008)
    bank.command(data, np.full(9, 0.31), 0.008)
    lead = options.timestep * 0.01 / 0.008 if implicit else 0.0
    np.testing.assert_allclose(data.ctrl, 0.31 + lead)


def test_steady_hold_has_no_tension_chatter():
    """Gravity on, the arm bent and held by its motors (elastic cables, PI loops at the
    125 Hz tick): after settling, every cable's tension above 10 Hz stays within 0.5 N
    peak-to-peak, recorded every physics step (issue 12's steady-stage criterion)."""
    from scipy.signal import butter, sosfiltfilt

    from continuum_sim.kinematics import cable_lengths
    from continuum_sim.model.cable_elasticity import pretension_offsets
    from continuum_sim.model.state import set_arm_configuration

    geometry = ArmGeometry()
    options = ModelOptions(joint="hinge_pair", timestep=0.004, cable_model="elastic")
    model = _compile(build_single_arm_model(geometry, options, tool="grinder"))
    data = mujoco.MjData(model)
    q = np.radians([40.0, 0.0, 30.0, 90.0, 20.0, 180.0])
    set_arm_configuration(model, data, geometry, "arm", q, "hinge_pair")
    mujoco.mj_forward(model, data)
    cables = np.arange(model.nu)
    bank = arm_motor_bank(model, cables, cables, options)
    set_points = cable_lengths(geometry, q) - pretension_offsets(geometry, options, 30.0)
    bank.reset(data, set_points)
    tensions = []
    for tick in range(int(3.0 / 0.008)):
        bank.command(data, set_points, 0.008)
        for _ in range(2):
            mujoco.mj_step(model, data)
            if tick * 0.008 >= 1.5:
                tensions.append(-data.actuator_force.copy())
    tensions = np.array(tensions)
    assert tensions.min() > 1.0  # taut
    high = sosfiltfilt(butter(4, 10.0, "highpass", fs=250.0, output="sos"), tensions, axis=0)
    assert np.ptp(high, axis=0).max() <= 0.5


def test_plan_is_read_between_samples():
    """The 125 Hz tick reads the 100 Hz plan by linear interpolation, not the nearest sample
    (the nearest sample repeated every fifth tick: the 25 Hz beat behind the chatter)."""
    from types import SimpleNamespace

    from continuum_sim.controllers import plan_at

    t = np.arange(0.0, 1.0, 0.01)
    q = np.stack([t, 2 * t], axis=1)
    tcp = np.zeros((len(t), 4, 4))
    tcp[:, 0, 3] = t
    plan = SimpleNamespace(t=t, q=lambda arm: q, tcp=lambda arm: tcp)
    ticks = np.arange(0.0, 0.9, 0.008)
    read = np.array([plan_at(plan, "left", s)[0][0] for s in ticks])
    np.testing.assert_allclose(read, ticks, atol=1e-12)  # a ramp stays a ramp: constant rate
    assert plan_at(plan, "left", 5.0)[0][0] == pytest.approx(t[-1])  # clamped past the end


def _held_sample_tensions(implicit_spring: bool, until: float = 12.0):
    """Per-physics-step gripper-arm cable tensions of the default task from 8 s (the grasp
    closed on the welded sample, the grinder approaching and cutting) until ``until``."""
    import dataclasses

    from continuum_sim.controllers import controller_spec, load_controller
    from continuum_sim.model.options import model_geometry
    from continuum_sim.scenario.cable_friction import CableFrictionObserver
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.runner import build_scene_model, make_simulation
    from continuum_sim.scenario.simulate import CutterObserver, HealthCheck, Observer, simulate
    from continuum_sim.toolpath import plan_task

    config = ScenarioConfig.default()
    config = dataclasses.replace(config, model=dataclasses.replace(config.model, cable_implicit_spring=implicit_spring))
    plan = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    _, model = build_scene_model(config)
    sim = make_simulation(config, plan, model, load_controller(controller_spec(config)))
    gripper_arm = "right"
    rows: list[np.ndarray] = []

    class Tensions(Observer):
        def after_physics_step(self, sim):
            if sim.data.time >= 8.0:
                rows.append(-sim.data.actuator_force[sim.handles.cable_actuators[gripper_arm]].copy())

    hooks = [CutterObserver(sim), CableFrictionObserver(config.model.cable_friction, 1), Tensions(), HealthCheck()]
    result = simulate(sim, int(until / sim.control_period), hooks)
    assert result.failure is None
    assert bool(sim.data.eq_active[sim.handles.sample_weld])  # still welded: the grasp pins the tip
    return np.array(rows), 1.0 / sim.timestep


def test_held_grasp_has_no_tension_chatter_and_the_explicit_spring_is_its_cause():
    """The gripper arm holding the welded sample (default task, 8–12 s, every physics step):
    with the cable spring integrated linearly implicitly the part above 10 Hz is within
    0.5 N peak-to-peak on every cable; with the explicit spring (the former default) the
    same hold rings at ~20–25 Hz with tens of newtons — the 4 ms step, not the plant."""
    from scipy.signal import butter, sosfiltfilt

    for implicit in (True, False):
        tensions, rate = _held_sample_tensions(implicit)
        assert tensions.max() > 10.0  # the arm is loaded (a cable may be slack: one side of a bend)
        high = sosfiltfilt(butter(4, 10.0, "highpass", fs=rate, output="sos"), tensions, axis=0)[25:-25]
        ptp = np.ptp(high, axis=0).max()
        if implicit:
            assert ptp <= 0.5, ptp
        else:
            assert ptp >= 5.0, ptp  # the explicit spring rings: the cause is the integration, shown
            spectrum = np.abs(np.fft.rfft(high[:, np.argmax(np.ptp(high, axis=0))]))
            peak = np.fft.rfftfreq(len(high), 1.0 / rate)[np.argmax(spectrum)]
            assert 15.0 <= peak <= 30.0, peak


def test_stable_step_divides_the_step_for_stiff_cables_only():
    """The shipped rope keeps the 4 ms step; a 3.7 mm rope (≈1.7e6 N/m proximal) gets the
    smallest whole division that brings k·h² within the verified limit; off: as configured."""
    from continuum_sim.model.cable_elasticity import CABLE_STEP_LIMIT, cable_stiffness, stable_timestep

    geometry = ArmGeometry()
    shipped = ModelOptions(timestep=0.004)
    assert stable_timestep(geometry, shipped) == 0.004
    stiff = ModelOptions(timestep=0.004, rope_diameter=0.0037)
    h = stable_timestep(geometry, stiff)
    k = cable_stiffness(geometry, stiff).max()
    n = round(0.004 / h)
    assert 0.004 / h == pytest.approx(n) and n >= 2
    assert k * h * h <= CABLE_STEP_LIMIT < k * (0.004 / (n - 1)) ** 2  # the smallest such n
    assert stable_timestep(geometry, ModelOptions(timestep=0.004, rope_diameter=0.0037, stable_step=False)) == 0.004
    lumped = ModelOptions(timestep=0.004, cable_model="lumped", cable_kp=1.0e6)
    assert 1.0e6 * stable_timestep(geometry, lumped) ** 2 <= CABLE_STEP_LIMIT


def test_stiff_cables_run_at_the_stable_step_without_diverging():
    """1e6 N/m-class cables diverged at the 4 ms step (saturated, flailing arm); the run now
    resolves its step first, records it, and the clamping stage runs to its end."""
    from continuum_sim.scenario.config import ScenarioConfig, merged
    from continuum_sim.scenario.runner import run_scenario

    config = merged(ScenarioConfig.default(), {"model": {"rope_diameter": 0.0037}})
    metrics = run_scenario(config, None, stages=("initial", "clamping"))
    assert metrics["timestep_s"] == pytest.approx(0.002)
    assert "diverged" not in metrics and metrics["task"]["failure"] == "partial_run"


def test_stable_step_divides_the_step_for_hinges_above_the_verified_range():
    """Hinges ×8 (the top of the design range) keep 4 ms; ×16, which diverged at 4 ms, gets 2 ms."""
    from continuum_sim.model.cable_elasticity import JOINT_STEP_LIMIT, stable_timestep, stiffest_joint

    geometry = ArmGeometry()
    assert stable_timestep(geometry, ModelOptions(timestep=0.004, stiffness_scale=8.0)) == 0.004
    stiff = ModelOptions(timestep=0.004, stiffness_scale=16.0)
    assert stable_timestep(geometry, stiff) == pytest.approx(0.002)
    assert stiffest_joint(geometry, stiff) * 0.002**2 <= JOINT_STEP_LIMIT < stiffest_joint(geometry, stiff) * 0.004**2
    assert stiffest_joint(geometry, ModelOptions(stiffness_scale=16.0)) == pytest.approx(16 * stiffest_joint(geometry, ModelOptions()))
