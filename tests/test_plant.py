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
from continuum_sim.model.motors import MotorBank, MotorRatings, arm_motor_bank
from continuum_sim.model.options import ModelOptions

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


def test_lumped_model_passes_set_points_through():
    geometry = ArmGeometry()
    options = ModelOptions(cable_model="lumped")
    model = _compile(build_single_arm_model(geometry, options, gravity=False))
    np.testing.assert_allclose(model.actuator_gainprm[:, 0], options.cable_kp)
    data = mujoco.MjData(model)
    bank = arm_motor_bank(model, np.arange(9), np.arange(9), options)
    bank.command(data, np.full(9, 0.3), 0.008)
    bank.command(data, np.full(9, 0.31), 0.008)
    np.testing.assert_allclose(data.ctrl, 0.31)


def test_steady_hold_has_no_tension_chatter():
    """Gravity on, the arm bent and held by its motors (elastic cables, PI loops at the
    125 Hz tick): after settling, every cable's tension above 10 Hz stays within 0.5 N
    peak-to-peak, recorded every physics step (issue 12's steady-stage criterion)."""
    from scipy.signal import butter, sosfiltfilt

    from continuum_sim.kinematics import cable_lengths
    from continuum_sim.model.motors import pretension_offsets
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
