"""Controller settings (SPEC §7): the paper's open loop or ours, gains and bounds.

A light module (no numba, no MuJoCo): loading a scenario configuration imports it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

from ..configio import ConfigError, require_positive, require_range

_CONTROLLER_SPEC = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_]\w*")


@dataclass(frozen=True)
class ControlConfig:
    """Controller settings; ``mode`` switches between the paper's open loop and ours."""

    mode: Literal["open", "closed"] = "closed"
    # "" = the built-in controller named by ``mode``; "package.module:ClassName" = your own class
    # (``continuum_sim.controllers.Controller`` protocol; checked when the run starts).
    controller: str = ""
    rate_hz: float = 125.0  # control (set-point) update rate (rounded to whole steps); the motor loops run every step
    # N, tension every cable keeps at the planned shape. 30 N (15 % of the 200 N motor rating):
    # with the strain-limited leaves a bend needs ~100 N on its inner cables, whose stretch
    # unloads the outer ones; at 10 N a quarter of the task's records had a slack cable.
    pretension: float = 30.0
    outer_gain: float = 8.0  # 1/s, integral gain of the task-space correction (gain_mode "plant": the loop's crossover ω_c)
    # "fixed": the correction integrates outer_gain × the bending-coordinate error; "plant":
    # the gain is derived per arm from the plant (continuum_sim.gains, docs/plant.md "Outer-loop
    # gains from the plant"): G = ω_c·R⁻¹ with R the static transmission (cable stretch against
    # the hinge stiffness), ω_c = min(outer_gain, mode_fraction × the arm's first bending mode ω₁).
    gain_mode: Literal["fixed", "plant"] = "fixed"
    mode_fraction: float = 0.5  # gain_mode "plant": cap of the crossover as a fraction of the arm's first mode ω₁
    # Proportional share of the pose error added to the command. It feeds the pose measured
    # every tick straight back: at 2 it rang the ~20-25 Hz cable-arm mode (docs/plant.md).
    outer_proportional: float = 0.5
    orientation_weight: float = 0.1  # m/rad: how much 1 rad of tool tilt counts against 1 m
    damping: float = 1e-4  # damped-least-squares regulariser (m²)
    max_correction_deg: float = 15.0  # bound on the correction per section (bending angle)
    # Tension keeping (closed mode): each section's three cables are shortened together
    # (a common mode that does not bend the section) until its slackest cable pulls at
    # least min_tension, as measured by the motors; 0 switches it off.
    min_tension: float = 3.0  # N
    tension_gain: float = 5.0  # 1/s
    max_extra_tension: float = 30.0  # N, bound on the added common-mode pull per section

    def __post_init__(self) -> None:
        if self.mode not in ("open", "closed"):
            raise ConfigError("mode", f"must be 'open' or 'closed' (got {self.mode!r})")
        if self.controller and not _CONTROLLER_SPEC.fullmatch(self.controller):
            raise ConfigError(
                "controller", f"must be empty or 'package.module:ClassName' (got {self.controller[:80]!r})"
            )
        require_range("rate_hz", self.rate_hz, 1.0, 10000.0, low_inclusive=True)
        require_range("pretension", self.pretension, 0.0, 1000.0, low_inclusive=True)
        require_range("outer_gain", self.outer_gain, 0.0, 1000.0, low_inclusive=True)
        if self.gain_mode not in ("fixed", "plant"):
            raise ConfigError("gain_mode", f"must be 'fixed' or 'plant' (got {self.gain_mode!r})")
        require_range("mode_fraction", self.mode_fraction, 0.0, 1.0)
        require_range("outer_proportional", self.outer_proportional, 0.0, 10.0, low_inclusive=True)
        require_positive("orientation_weight", self.orientation_weight)
        require_range("damping", self.damping, 0.0, 1.0, low_inclusive=True)
        require_range("max_correction_deg", self.max_correction_deg, 0.0, 90.0, low_inclusive=True)
        require_range("min_tension", self.min_tension, 0.0, 1000.0, low_inclusive=True)
        require_range("tension_gain", self.tension_gain, 0.0, 1000.0, low_inclusive=True)
        require_range("max_extra_tension", self.max_extra_tension, 0.0, 1000.0, low_inclusive=True)
