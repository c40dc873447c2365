"""Limits that protect the machine, checked before any work (docs/errors.md "Limits").

A valid-looking configuration can still ask for hours of stepping or gigabytes of
arrays: a 1e-9 s timestep is 8 million MuJoCo steps per control tick, a 1e-7 m/s cut
speed a plan of 10^8 samples. These checks run before planning or building, name the
field to change, and are cheap (no model is compiled, no plan is made). Cross-part
checks that need two parts of the scenario (arm × model segment count) also live here,
so the CLI and the sweep spec check both use them.
"""

from __future__ import annotations

import math
from typing import Any

from .configio import ConfigError

MAX_STEPS_PER_TICK = 1_000  # MuJoCo steps per control tick (default: 2 at 4 ms and 125 Hz)
MAX_SIM_STEPS = 20_000_000  # steps per run (default run: ~13,000); ~2 h at 300 µs/step
# The plan's own limit (samples) is toolpath.MAX_PLAN_SAMPLES: the planner checks it while it lays out the moves.


def steps_per_tick(config: Any) -> int:
    """MuJoCo steps between two control ticks, as the runner rounds them."""
    return max(1, int(round(1.0 / (config.control.rate_hz * config.model.timestep))))


def check_model_geometry(config: Any) -> None:
    """The arm × ``model.segments_per_section`` combination: disks must not overlap."""
    from .model.options import model_geometry

    n = config.model.segments_per_section
    if n == 0:
        return
    try:
        model_geometry(config.arm, config.model)
    except ConfigError:
        most = min(math.ceil(s.length / config.arm.disk_thickness) - 1 for s in config.arm.sections)
        raise ConfigError(
            "model.segments_per_section",
            f"{n} segments make the disks overlap (segment pitch below arm.disk_thickness = {config.arm.disk_thickness:g} m); "
            f"must satisfy 0 <= segments_per_section <= {most} for this arm (0 = physical count)",
        ) from None


def check_scenario(config: Any) -> None:
    """Every check a scenario config needs before planning: cross-part geometry, steps per tick."""
    check_model_geometry(config)
    per_tick = steps_per_tick(config)
    if per_tick > MAX_STEPS_PER_TICK:
        raise ConfigError(
            "model.timestep",
            f"{config.model.timestep:g} s gives {per_tick} MuJoCo steps per control tick at control.rate_hz = "
            f"{config.control.rate_hz:g}; at most {MAX_STEPS_PER_TICK} allowed "
            f"(timestep >= {1.0 / (config.control.rate_hz * MAX_STEPS_PER_TICK):.3g} s)",
        )


def check_run_length(config: Any, duration_s: float) -> None:
    """Steps a run of ``duration_s`` simulated seconds takes; refused above ``MAX_SIM_STEPS``."""
    steps = duration_s / config.model.timestep
    if steps > MAX_SIM_STEPS:
        raise ConfigError(
            "model.timestep",
            f"the {duration_s:.4g} s task at {config.model.timestep:g} s per step is {steps:.3g} MuJoCo steps; "
            f"at most {MAX_SIM_STEPS:.3g} allowed (larger timestep, or faster plan speeds)",
        )


def check_cameras(config: Any) -> None:
    """Video cameras must exist in the scene (checked before the run, not when the first frame renders)."""
    from .model.scene import build_scene

    root = build_scene(config.arm, config.layout, config.model, config.scene)
    known = [c.full_identifier for c in root.find_all("camera") if c.name]
    for i, name in enumerate(config.simulation.cameras):
        if name not in known:
            raise ConfigError(f"simulation.cameras[{i}]", f"unknown camera {name[:40]!r}; the scene has {', '.join(known)}")
