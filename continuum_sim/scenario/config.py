"""Scenario configuration: everything one run needs, validated, saved with every run.

The shipped defaults live in ``continuum_sim/data/scenario.toml``; a user's TOML file
overrides any subset of them (unknown keys are errors). Every numeric field can be
addressed by a dotted path (``model.stiffness_scale``, ``arm.sections.0.hinge_width``),
which is how sweeps vary a design.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

from ..configio import ConfigError, config_from_file, dumps_toml, from_dict, require_int, require_range, save_toml, to_dict
from ..control.config import ControlConfig
from ..geometry import ArmGeometry
from ..layout import TaskLayout
from ..model.options import ModelOptions
from ..model.scene_options import SceneOptions
from ..toolpath import PlanConfig


def _scenario_model_options() -> ModelOptions:
    """The scenario's default fidelity: the physical 10 joints per section, hinge pairs, 4 ms.

    Hinge pairs rather than ball joints: the flexure leaves make a segment stiff in twist,
    which MuJoCo's isotropic ball-joint spring cannot represent; under the grasp and
    gravity loads the ball model twists, a motion PCC has no coordinate for, so the
    closed loop cannot remove it (clamping-stage error 10 mm with ball joints vs 1.1 mm
    with hinge pairs), and hinge pairs step twice as fast. Fewer joints per section
    would be faster still but lower the cable-compression buckling load ∝ n² (the
    cables' pre-tension then softens the arm visibly). 4 ms: implicitfast integrates the
    cable and joint damping implicitly, and every scenario metric stays within its goal
    at 2, 3 and 4 ms (at 5 ms the grasp loses the sample); see README "Speed". Dense
    constraint Jacobians: the solver's islands here are one arm (60+ dofs, a dense block
    anyway), and the sparse path measured 1.5-2.5× slower in the constraint phase.
    """
    return ModelOptions(joint="hinge_pair", timestep=0.004, jacobian="dense", flexure_model="nonlinear")


@dataclass(frozen=True)
class SimulationConfig:
    """How a run is simulated and recorded."""

    seed: int = 0  # seeds the sensor noise below (no effect while it is 0)
    # Gaussian noise (standard deviation, m, per axis) on the tool-centre positions the controller
    # measures (*assumed* 0: the paper's robot has no tool-pose sensor; set it to study robustness).
    tcp_noise_m: float = 0.0
    record_hz: float = 62.5  # time-series sampling rate (rounded to whole control ticks)
    video_fps: float = 20.0
    video_shadows: bool = False  # shadows and MSAA triple the frame time under software GL
    video_overlay: bool = True  # time, stage, cut %, spindle speed, cutting force over the frames (docs/video.md)
    video_width: int = 640
    video_height: int = 480
    cameras: tuple[str, ...] = ("overview", "closeup")

    def __post_init__(self) -> None:
        require_int("seed", self.seed, 0)
        require_range("tcp_noise_m", self.tcp_noise_m, 0.0, 0.1, low_inclusive=True)
        require_range("record_hz", self.record_hz, 1.0, 1000.0, low_inclusive=True)
        require_range("video_fps", self.video_fps, 1.0, 120.0, low_inclusive=True)
        require_int("video_width", self.video_width, 16, 4096)
        require_int("video_height", self.video_height, 16, 4096)
        if not isinstance(self.video_overlay, bool):
            raise ConfigError("video_overlay", f"must be true or false (got {self.video_overlay!r})")
        if not self.cameras:
            raise ConfigError("cameras", "must name at least one camera")


@dataclass(frozen=True)
class ScenarioConfig:
    """One run of the sample-removal task."""

    arm: ArmGeometry = field(default_factory=ArmGeometry)
    layout: TaskLayout = field(default_factory=TaskLayout)
    model: ModelOptions = field(default_factory=_scenario_model_options)
    scene: SceneOptions = field(default_factory=SceneOptions)  # tools (gripper, grinder), kerf cells, foam
    plan: PlanConfig = field(default_factory=PlanConfig)
    control: ControlConfig = field(default_factory=ControlConfig)
    simulation: SimulationConfig = field(default_factory=SimulationConfig)

    @classmethod
    def default(cls) -> ScenarioConfig:
        """The shipped defaults (``continuum_sim/data/scenario.toml``)."""
        text = resources.files("continuum_sim").joinpath("data/scenario.toml").read_text()
        import tomllib

        return from_dict(cls, tomllib.loads(text))

    @classmethod
    def from_toml(cls, path: str | os.PathLike[str]) -> ScenarioConfig:
        """A user file over the shipped defaults; errors name the file and the field."""
        return config_from_file(path, lambda data: merged(cls.default(), data))

    def save_toml(self, path: str | os.PathLike[str]) -> None:
        save_toml(self, path)


def _merge(base: Any, override: Any) -> Any:
    if isinstance(base, dict) and isinstance(override, dict):
        out = dict(base)
        for key, value in override.items():
            out[key] = _merge(base[key], value) if key in base else value
        return out
    return override


def merged(config: ScenarioConfig, overrides: dict[str, Any]) -> ScenarioConfig:
    """``config`` with a nested dict of overrides applied (lists replace whole)."""
    return from_dict(type(config), _merge(to_dict(config), overrides))


DEFAULTS_HEADER = """\
# Shipped defaults of the sample-removal scenario (continuum_sim.scenario.config).
# Generated from the dataclass defaults by `continuum-sim build-model`; a test fails when stale.
# Units: SI (m, kg, N, s, Pa); angles in degrees where the key ends in _deg.

"""


def default_scenario_toml() -> str:
    """The text of the shipped defaults file, generated from the dataclass defaults."""
    return DEFAULTS_HEADER + dumps_toml(to_dict(ScenarioConfig()))
