"""The run pipeline: typed trajectory, pure metrics, observers and controllers in the tick loop."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from continuum_sim.controllers import MotorCommands, PlanTrackingController
from continuum_sim.model.options import model_geometry
from continuum_sim.scenario import metrics as met
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.scenario.runner import build_scene_model, make_simulation, recompute_metrics, run_scenario
from continuum_sim.scenario.simulate import Observer, simulate
from continuum_sim.scenario.trajectory import Trajectory
from continuum_sim.toolpath import plan_task

STAGES = ("initial",)


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("short")
    config = ScenarioConfig.default()
    return out, config, run_scenario(config, out, stages=STAGES)


def test_trajectory_round_trips_and_metrics_recompute_exactly(short_run):
    out, config, metrics = short_run
    trajectory = Trajectory.load(out / "trajectory.npz")
    assert trajectory.stages_run == STAGES and trajectory.failure is None
    again = Trajectory.load(out / "trajectory.npz")
    assert trajectory.to_bytes() == again.to_bytes()
    plan = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    recomputed = met.compute_metrics(trajectory, plan, config)
    written = json.loads((out / "metrics.json").read_text())
    # The trajectory holds no wall-clock figures (identical runs, identical files): recompute_metrics
    # carries metrics.json's over, every other key is recomputed from the file alone.
    assert recomputed["wall_seconds"] is None and recomputed["wall_real_time_factor"] is None and recomputed["cpu_seconds"] is None
    assert {k: v for k, v in recomputed.items() if k not in met.WALL_CLOCK_METRICS} == \
        {k: v for k, v in written.items() if k not in met.WALL_CLOCK_METRICS}
    assert json.dumps(recompute_metrics(out), indent=2, sort_keys=True) == (out / "metrics.json").read_text()


class _Counter(Observer):
    """Counts hook calls; pushes the gripper arm's first disk with a constant per-step force."""

    def __init__(self, force: float) -> None:
        self.force = force
        self.calls = {"start": 0, "before_tick": 0, "before_physics_step": 0, "after_physics_step": 0, "after_tick": 0,
                      "close": 0}

    def start(self, sim):
        self.calls["start"] += 1
        self.body = int(sim.handles.disk_bodies[sim.handles.gripper_arm][0])

    def before_tick(self, sim):
        self.calls["before_tick"] += 1

    def before_physics_step(self, sim):
        self.calls["before_physics_step"] += 1
        sim.data.xfrc_applied[self.body, 0] = self.force

    def after_physics_step(self, sim):
        self.calls["after_physics_step"] += 1

    def after_tick(self, sim):
        self.calls["after_tick"] += 1
        return "stop here" if sim.tick == 9 else None

    def close(self, sim):
        self.calls["close"] += 1


_PLANS: dict = {}


def _simulation(config):
    if id(config) not in _PLANS:
        _PLANS[id(config)] = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    plan = _PLANS[id(config)]
    _, model = build_scene_model(config)
    return make_simulation(config, plan, model, PlanTrackingController())


def test_observer_hooks_run_per_tick_and_per_physics_step_and_can_stop_the_run():
    config = ScenarioConfig.default()
    sim = _simulation(config)
    counter = _Counter(force=0.0)
    result = simulate(sim, 50, [counter])
    assert result.failure == "stop here" and result.ticks == 10
    n = sim.control_every
    assert counter.calls == {"start": 1, "before_tick": 10, "before_physics_step": 10 * n,
                             "after_physics_step": 10 * n, "after_tick": 10, "close": 1}
    # Single steps with a hook are the same physics as MuJoCo's batched steps without one.
    plain = _simulation(config)
    simulate(plain, 10, [])
    np.testing.assert_array_equal(plain.data.qpos, sim.data.qpos)
    # A per-step force acts: the pushed arm moves.
    pushed = _simulation(config)
    simulate(pushed, 10, [_Counter(force=5.0)])
    assert np.abs(pushed.data.qpos - plain.data.qpos).max() > 1e-4


class _Frozen:
    """A custom controller: holds every motor where the first call found it."""

    def reset(self, context):
        self.first: MotorCommands | None = None
        self.inner = PlanTrackingController("open")
        self.inner.reset(context)

    def command(self, state):
        if self.first is None:
            self.first = self.inner.command(state)
        return self.first


def test_a_custom_controller_drives_the_run():
    metrics = run_scenario(ScenarioConfig.default(), None, stages=STAGES, controller=_Frozen())
    assert metrics["stages_run"] == list(STAGES)
    assert np.isfinite(metrics["tip_error_mm"]["left"]["all"]["mean"])


def test_metrics_command_reproduces_metrics_json(short_run, capsys):
    from continuum_sim.cli import main

    out, _, _ = short_run
    assert main(["metrics", str(out)]) == 0
    assert capsys.readouterr().out == (out / "metrics.json").read_text() + "\n"
    assert main(["metrics", str(out / "plots")]) == 2  # not a run folder: one line, exit 2
    assert "has no config.toml" in capsys.readouterr().err


def test_seed_drives_the_sensor_noise_and_nothing_else():
    from continuum_sim.scenario.config import merged

    base = ScenarioConfig.default()
    plan = plan_task(model_geometry(base.arm, base.model), base.layout, base.plan)

    def qpos(seed: int, noise: float) -> bytes:
        config = merged(base, {"simulation": {"seed": seed, "tcp_noise_m": noise}})
        _, model = build_scene_model(config)
        sim = make_simulation(config, plan, model, PlanTrackingController())
        simulate(sim, 40, [])
        return sim.data.qpos.tobytes()

    assert qpos(0, 0.0) == qpos(7, 0.0)  # no noise: the seed has nothing to draw
    noisy = qpos(0, 2e-4)
    assert noisy == qpos(0, 2e-4) and noisy != qpos(7, 2e-4) and noisy != qpos(0, 0.0)
