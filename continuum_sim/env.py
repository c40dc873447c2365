"""Gymnasium environment of the sample-removal task: ``continuum_sim/SampleRemoval-v0``.

    import gymnasium as gym
    import continuum_sim.env  # registers the id
    env = gym.make("continuum_sim/SampleRemoval-v0")

One episode is one run of the task (``run_scenario``'s plan, scene and tick loop). An agent
acts every ``ticks_per_step`` control ticks (default 5: 25 Hz at the 125 Hz control rate).

Action (``Box(-1, 1, (2, 2·sections))``): per arm (``layout.ARMS`` order), a correction in
bending coordinates (u, v) = θ·(cos φ, sin φ) per section, scaled by
``max_correction_rad``, added to the shape the built-in controller is asked to follow.
Bending coordinates rather than cable-length offsets: they are the PCC model's own smooth
coordinates (no wrap of φ, zero at the straight arm), the built-in controller already maps
them to cable lengths with pre-tension, and a zero action is exactly the built-in controller
(``base_controller``: ``"closed"`` by default, or ``"open"``).

Observation (``Dict``): ``tool_pose`` (2, 12): measured tool-centre position (m) and frame
(row-major 3×3) per arm; ``tool_error`` (2, 3): planned minus measured tool-centre
position (m); ``cable_length`` (2, 3·sections) m and ``cable_tension`` (2, 3·sections) N as
the motors measure them (the arm's shape as its sensors see it); ``stage`` (task stage index,
``TaskPlan.stage_names``); ``progress`` (fraction of the plan's time done, and of the kerf cut).

Reward per step: ``-(e_grinder + e_gripper) / 1 mm · 0.01`` (tool-centre errors) ``+ 10 ·``
(fraction of the kerf cut during the step) ``+ 10`` once on success.
Terminated: success (the plan's end is reached with the sample cut free and held) or failure
(divergence, the arms touching, the sample dropped: free but neither held nor on the plate,
or the plan's end without success). ``info`` holds ``success`` and ``failure``.
"""

from __future__ import annotations

from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from . import kinematics as kin
from .controllers import MeasuredState, PlanTrackingController
from .scenario.config import ScenarioConfig

ENV_ID = "continuum_sim/SampleRemoval-v0"
HELD_DISTANCE_M = 0.05  # the sample is held when within this of the gripper's tool centre


class CorrectedController(PlanTrackingController):
    """The built-in controller following the plan shifted by a bending-coordinate offset per arm."""

    def __init__(self, mode: Literal["open", "closed"]) -> None:
        super().__init__(mode)
        self.offset: dict[str, NDArray[np.float64]] = {}

    def planned(self, arm: str, state: MeasuredState) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        q, tcp = super().planned(arm, state)
        offset = self.offset.get(arm)
        if offset is None or not np.any(offset):
            return q, tcp
        return kin.from_bending(kin.to_bending(q) + offset), tcp


class SampleRemovalEnv(gym.Env[dict[str, Any], NDArray[np.float32]]):
    """The dual-arm sample-removal task as a Gymnasium environment (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 25}

    def __init__(
        self,
        config: ScenarioConfig | None = None,
        *,
        ticks_per_step: int = 5,
        max_correction_rad: float = 0.05,
        base_controller: Literal["open", "closed"] = "closed",
        stages: tuple[str, ...] | None = None,
        render_mode: str | None = None,
    ) -> None:
        from .model.options import model_geometry
        from .scenario.runner import build_run_model, plan_extent, with_stable_step
        from .toolpath import plan_task

        self.config = with_stable_step(ScenarioConfig.default() if config is None else config)
        if ticks_per_step < 1:
            raise ValueError(f"ticks_per_step: must be >= 1 (got {ticks_per_step})")
        if base_controller not in ("open", "closed"):
            raise ValueError(f"base_controller: must be 'open' or 'closed' (got {base_controller!r})")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode: must be None or 'rgb_array' (got {render_mode!r})")
        self.ticks_per_step = int(ticks_per_step)
        self.max_correction = float(max_correction_rad)
        self.base_controller = base_controller
        self.render_mode = render_mode
        cfg = self.config
        self.geometry = model_geometry(cfg.arm, cfg.model)
        self.plan = plan_task(self.geometry, cfg.layout, cfg.plan)  # once: deterministic, the costly part
        self.stages_run, self.end_time = plan_extent(self.plan, stages)
        # A run of the whole task succeeds with the sample cut free and held; one limited to
        # earlier stages (tests, curricula) succeeds by reaching their end without a failure.
        self.whole_task = self.stages_run[-1] == self.plan.stage_names[-1]
        _, self.model, self.render_model = build_run_model(cfg)  # render: the spatial twin draws the cables
        n = 2 * self.geometry.n_sections
        c = 3 * self.geometry.n_sections
        self.action_space = spaces.Box(-1.0, 1.0, (2, n), dtype=np.float32)
        big = np.float32(1e3)
        self.observation_space = spaces.Dict({
            "tool_pose": spaces.Box(-big, big, (2, 12), dtype=np.float32),
            "tool_error": spaces.Box(-big, big, (2, 3), dtype=np.float32),
            "cable_length": spaces.Box(-big, big, (2, c), dtype=np.float32),
            "cable_tension": spaces.Box(-big, big, (2, c), dtype=np.float32),
            "stage": spaces.Discrete(len(self.plan.stage_names)),
            "progress": spaces.Box(0.0, 1.0, (2,), dtype=np.float32),
        })
        self._renderer: Any = None
        self.sim: Any = None
        self.loop: Any = None

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        import dataclasses

        from .scenario.cable_friction import CableFrictionObserver
        from .scenario.flexure_observer import flexure_observers
        from .scenario.runner import make_simulation
        from .scenario.simulate import CutterObserver, HealthCheck, TickLoop

        super().reset(seed=seed, options=options)  # no options of its own
        cfg = self.config
        if seed is not None:  # the seed drives the (optional) sensor noise, as simulation.seed does for a run
            cfg = dataclasses.replace(cfg, simulation=dataclasses.replace(cfg.simulation, seed=int(seed)))
        if self.sim is not None:
            from .plant.cable_path import release_data

            self.loop.close()
            release_data(self.sim.data)
        self.controller = CorrectedController(self.base_controller)
        self.sim = make_simulation(cfg, self.plan, self.model, self.controller)
        self.sim.render_model = self.render_model
        self.cutter = CutterObserver(self.sim)
        friction = CableFrictionObserver(cfg.model.cable_friction, 1)  # the same physics hooks as run_scenario
        physics = [self.cutter, friction, *flexure_observers(cfg), HealthCheck()]  # the same physics hooks as run_scenario
        self.loop = TickLoop(self.sim, physics)  # run's tick loop, one tick at a time
        self.n_ticks = int(np.ceil(self.end_time / self.sim.control_period))
        self._cut_fraction = 0.0
        self._cut_errors: list[float] = []
        return self._observation(), {"success": False, "failure": None}

    @property
    def tick(self) -> int:
        return self.loop.ticks

    def step(self, action: NDArray[np.float32]) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        if self.sim is None:
            raise RuntimeError("call reset() before step()")
        a = np.clip(np.asarray(action, dtype=float).reshape(self.action_space.shape), -1.0, 1.0)
        sim, data = self.sim, self.sim.data
        self.controller.offset = {arm: self.max_correction * a[k] for k, arm in enumerate(sim.handles.arms)}
        failure = None
        for _ in range(self.ticks_per_step):
            if self.tick >= self.n_ticks:
                break
            index = sim.plan_index_at(data.time)
            if self.plan.cutting[index]:  # the grinder's tool-centre error while cutting (as run's metric)
                grinder = sim.handles.grinder_arm
                planned = self.plan.tcp(grinder)[index][:3, 3]
                self._cut_errors.append(float(np.linalg.norm(planned - data.site_xpos[sim.handles.tcp_site[grinder]])))
            failure = self.loop.tick()
            if failure is not None:
                break
        obs = self._observation()
        errors = np.linalg.norm(obs["tool_error"].astype(float), axis=1)
        cut = self._cut()
        reward = -0.01 * float(errors.sum()) / 1e-3 + 10.0 * (cut - self._cut_fraction)
        self._cut_fraction = cut
        failure = failure or self._task_failure()
        success = failure is None and self.tick >= self.n_ticks and (self._held() or not self.whole_task)
        if failure is None and self.tick >= self.n_ticks and not success:
            failure = "the plan ended without the sample cut free and held"
        if success:
            reward += 10.0
        terminated = success or failure is not None
        info: dict[str, Any] = {"success": bool(success), "failure": failure}
        if terminated:
            errors_mm = 1000.0 * np.array(self._cut_errors)
            info["cutting_tip_error_mm_mean"] = float(errors_mm.mean()) if errors_mm.size else None
            info["sample_detached"] = not bool(data.eq_active[sim.handles.sample_weld])
        return obs, float(reward), bool(terminated), False, info

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode != "rgb_array" or self.sim is None:
            return None
        import mujoco

        from .video import pose_for_drawing

        if self._renderer is None:
            self._renderer = mujoco.Renderer(self.render_model, 240, 320)
            self._render_data = mujoco.MjData(self.render_model)
        d = self.sim.data
        pose_for_drawing(self.render_model, self._render_data, d.time, d.qpos, d.mocap_pos, d.mocap_quat, self.model.geom_rgba)
        self._renderer.update_scene(self._render_data, camera=self.config.simulation.cameras[0])
        return self._renderer.render()

    def close(self) -> None:
        if self.sim is not None:
            from .plant.cable_path import release_data

            self.loop.close()
            release_data(self.sim.data)
            self.sim = None
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ helpers
    def _observation(self) -> dict[str, Any]:
        sim = self.sim
        state = sim.measure(sim)
        t = state.time
        pose, error, length, tension = [], [], [], []
        for arm in sim.handles.arms:
            m = state.arms[arm]
            _, tcp_plan = self.controller.planned(arm, state)
            pose.append(np.concatenate([m.tcp_pos, m.tcp_mat.ravel()]))
            error.append(tcp_plan[:3, 3] - m.tcp_pos)
            length.append(m.cable_length)
            tension.append(m.cable_tension)
        progress = min(t / self.end_time, 1.0) if self.end_time > 0 else 1.0
        return {
            "tool_pose": np.array(pose, dtype=np.float32),
            "tool_error": np.array(error, dtype=np.float32),
            "cable_length": np.array(length, dtype=np.float32),
            "cable_tension": np.array(tension, dtype=np.float32),
            "stage": int(self.plan.stage[sim.plan_index_at(t)]),
            "progress": np.array([progress, self._cut()], dtype=np.float32),
        }

    def _cut(self) -> float:
        cutter = self.cutter.cutter
        return 1.0 - cutter.cells_remaining / max(cutter.n_cells, 1)

    def _held(self) -> bool:
        data, h = self.sim.data, self.sim.handles
        sample = data.xpos[h.sample_body]
        tcp = data.site_xpos[h.tcp_site[h.gripper_arm]]
        return not bool(data.eq_active[h.sample_weld]) and float(np.linalg.norm(sample - tcp)) < HELD_DISTANCE_M

    def _task_failure(self) -> str | None:
        from .scenario.simulate import contact_forces
        from .scenario.trajectory import CONTACT_KINDS

        sim = self.sim
        forces = contact_forces(sim.model, sim.data, sim.handles.geom_kind)
        if forces[CONTACT_KINDS.index("arm_arm")] > 0.0:
            return f"the arms touched at t = {sim.data.time:.3f} s"
        detached = not bool(sim.data.eq_active[sim.handles.sample_weld])
        plate_bottom = self.config.layout.plate.top_z - self.config.layout.plate.thickness
        if detached and not self._held() and sim.data.xpos[sim.handles.sample_body][2] < plate_bottom - 0.02:
            return f"the sample dropped at t = {sim.data.time:.3f} s"
        return None


gym.register(id=ENV_ID, entry_point="continuum_sim.env:SampleRemovalEnv")
