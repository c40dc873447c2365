"""The motors' compiled tick (plant/drive.py ``drive_motors``) against a vectorised numpy
oracle of the same equations, and MotorDrive's one call for every bank against each bank's own."""

from __future__ import annotations

import dataclasses

import numpy as np


def _oracle(x, integral, set_point, s, length, k, droop, kp, ki, max_speed, h, dt):
    """One tick of the PI encoder loops, numpy: (new position, new integral, actuator control).
    Backward Euler in (x, ∫e) with the cable's droop on taut cables; at the speed limit the
    command is ±v_max and the integrator holds."""
    v_ff = (s - set_point) / dt
    dk = np.where(length > x, droop * k, 0.0)
    a = kp + ki * dt
    x_new = (x + dt * (v_ff + a * s + ki * integral + dk * length)) / (1.0 + dt * (a + dk))
    v_cmd = v_ff + a * (s - x_new) + ki * integral
    saturated = np.abs(v_cmd) > max_speed
    x_sat = (x + dt * (np.clip(v_cmd, -max_speed, max_speed) + dk * length)) / (1.0 + dt * dk)
    x_new = np.where(saturated, x_sat, x_new)
    integral = np.where(saturated, integral, integral + dt * (s - x_new))
    return x_new, integral, 0.5 * (x + x_new) + h * (x_new - x) / dt


def _drive(config):
    from continuum_sim.controllers import controller_spec, load_controller
    from continuum_sim.model.options import model_geometry
    from continuum_sim.scenario.runner import build_scene_model, make_simulation, with_stable_step
    from continuum_sim.toolpath import plan_task

    config = with_stable_step(config)
    plan = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    _, model = build_scene_model(config)
    return make_simulation(config, plan, model, load_controller(controller_spec(config)))


def test_motor_tick_equals_the_numpy_oracle_and_the_fused_drive_the_banks():
    """The same commands to two drives, one fused (one kernel call), one bank by bank, with
    random set-point jumps (speed-saturated motors) and tendon lengths either side of the
    motors (taut and slack cables): every motor's position, integral and control agree with
    the numpy oracle within 1e-12 relative, and the two drives agree bit for bit."""
    from continuum_sim.controllers import MotorCommands
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.simulate import prime

    fused, banks = _drive(ScenarioConfig.default()), _drive(ScenarioConfig.default())
    banks.actuate.fused = False  # type: ignore[attr-defined]  # bank by bank: MotorBank.command
    assert fused.actuate.fused  # type: ignore[attr-defined]
    for sim in (fused, banks):
        prime(sim)
    rng = np.random.default_rng(7)
    base = fused.commands
    assert base is not None
    drive = fused.actuate
    all_banks = [*drive.banks.values(), drive.gripper]  # type: ignore[attr-defined]
    saturated = taut = slack = 0
    for tick in range(40):
        scale = 0.05 if tick % 7 == 3 else 1e-4  # every 7th tick a jump the motors cannot follow
        cable_lengths = {arm: v + rng.normal(0.0, scale, len(v)) for arm, v in base.cable_lengths.items()}
        commands = dataclasses.replace(base, cable_lengths=cable_lengths,
                                       gripper_cable=base.gripper_cable + rng.normal(0.0, scale))
        assert isinstance(commands, MotorCommands)
        tendons = np.concatenate([b.tendons for b in all_banks])
        lengths = fused.data.ten_length[tendons] + rng.normal(0.0, 2e-3, len(tendons))
        before = [(b.position.copy(), b.integral.copy(), b.set_point.copy()) for b in all_banks]
        for sim in (fused, banks):
            sim.tick = tick
            sim.data.ten_length[tendons] = lengths
            sim.actuate(sim, commands)
        dt = fused.control_period
        targets = [*commands.cable_lengths.values(), np.array([commands.gripper_cable])]
        for bank, (x, integral, set_point), target in zip(all_banks, before, targets, strict=True):
            length = fused.data.ten_length[bank.tendons]
            k = bank.stiffness(fused.data)
            r = bank.ratings
            want = _oracle(x, integral, set_point, target, length, k, r.droop, r.kp, r.ki, r.max_speed,
                           bank.implicit_step, dt)
            got = (bank.position, bank.integral, fused.data.ctrl[bank.actuators])
            for g, w in zip(got, want, strict=True):
                np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-15)
            saturated += int(np.sum((bank.integral == integral) & (bank.position != x)))  # anti-windup: ∫e held
            taut, slack = taut + int(np.sum(length > x)), slack + int(np.sum(length <= x))
        assert fused.data.ctrl.tobytes() == banks.data.ctrl.tobytes(), tick
        for name in ("actuator_gainprm", "actuator_biasprm"):
            assert getattr(fused.model, name).tobytes() == getattr(banks.model, name).tobytes(), (tick, name)
    assert saturated > 0 and taut > 0 and slack > 0  # both branches of the loop and of the spring ran
