"""MotorDrive's compiled fused update against each motor bank's own numpy update."""

from __future__ import annotations

import dataclasses

import numpy as np


def _drive(config):
    from continuum_sim.controllers import controller_spec, load_controller
    from continuum_sim.model.options import model_geometry
    from continuum_sim.scenario.runner import build_scene_model, make_simulation, with_stable_step
    from continuum_sim.toolpath import plan_task

    config = with_stable_step(config)
    plan = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    _, model = build_scene_model(config)
    return make_simulation(config, plan, model, load_controller(controller_spec(config)))


def test_fused_motor_update_is_the_banks_update_bit_for_bit():
    """The same commands to two drives, one fused (compiled), one bank by bank (numpy), with
    random set-point jumps (speed-saturated motors) and tendon lengths either side of the
    motors (taut and slack cables): controls, actuator parameters and motor states agree in
    every bit, tick after tick, also after a bank was reset on its own."""
    from continuum_sim.controllers import MotorCommands
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.simulate import prime

    fused, banks = _drive(ScenarioConfig.default()), _drive(ScenarioConfig.default())
    banks.actuate._fused = None  # type: ignore[attr-defined]  # bank by bank: MotorBank.command
    assert fused.actuate._fused is not None  # type: ignore[attr-defined]
    for sim in (fused, banks):
        prime(sim)
    rng = np.random.default_rng(7)
    base = fused.commands
    assert base is not None
    tendons = np.concatenate([b.tendons for b in fused.actuate._fused["banks"]])  # type: ignore[attr-defined]
    saturated = taut = slack = 0
    for tick in range(60):
        scale = 0.05 if tick % 7 == 3 else 1e-4  # every 7th tick a jump the motors cannot follow
        cable_lengths = {arm: v + rng.normal(0.0, scale, len(v)) for arm, v in base.cable_lengths.items()}
        commands = dataclasses.replace(base, cable_lengths=cable_lengths,
                                       gripper_cable=base.gripper_cable + rng.normal(0.0, scale))
        assert isinstance(commands, MotorCommands)
        lengths = fused.data.ten_length[tendons] + rng.normal(0.0, 2e-3, len(tendons))
        if tick == 40:
            for sim in (fused, banks):  # a bank reset on its own: the fused state is gathered anew
                bank = sim.actuate.banks["left"]  # type: ignore[attr-defined]
                bank.reset(sim.data, bank.set_point)
        state = fused.actuate._fused["banks"]  # type: ignore[attr-defined]
        before = np.concatenate([b.position for b in state]), np.concatenate([b.integral for b in state])
        for sim in (fused, banks):
            sim.tick = tick
            sim.data.ten_length[tendons] = lengths
            sim.actuate(sim, commands)
        after = np.concatenate([b.position for b in state]), np.concatenate([b.integral for b in state])
        saturated += int(np.sum((after[1] == before[1]) & (after[0] != before[0])))  # anti-windup: ∫e held
        taut, slack = taut + int(np.sum(lengths > before[0])), slack + int(np.sum(lengths <= before[0]))
        for name in ("ctrl",):
            assert getattr(fused.data, name).tobytes() == getattr(banks.data, name).tobytes(), (tick, name)
        for name in ("actuator_gainprm", "actuator_biasprm"):
            assert getattr(fused.model, name).tobytes() == getattr(banks.model, name).tobytes(), (tick, name)
        for a, b in zip(fused.actuate._fused["banks"], [*banks.actuate.banks.values(), banks.actuate.gripper],  # type: ignore[attr-defined]
                        strict=True):
            for attr in ("position", "integral", "set_point"):
                assert getattr(a, attr).tobytes() == getattr(b, attr).tobytes(), (tick, attr)
    assert saturated > 0 and taut > 0 and slack > 0  # both branches of the loop and of the spring ran
