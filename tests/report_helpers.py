"""Shared run and study folders for the report tests (one short run, one tiny sweep)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from continuum_sim.cli import main
from continuum_sim.scenario.config import ScenarioConfig, merged
from continuum_sim.scenario.runner import run_scenario

SEED = 7  # simulation.seed differs from the shipped default (0): the page must list it as an override
TINY_SWEEP = """metrics = ["sag_mm", "max_cable_tension_n"]
[grid]
"model.stiffness_scale" = [1.0, 2.0]
[evaluation]
kind = "gravity_sag"
settle_s = 0.2
"""


def make_short_run(out: Path) -> dict:
    """The task's first stage (0.5 s simulated; ~1.5 s CPU) as a run folder, plus a 12-frame video.mp4."""
    import imageio.v2 as imageio

    config = merged(ScenarioConfig.default(), {"simulation": {"seed": SEED}})
    metrics = run_scenario(config, out, stages=("initial",))
    frames = [np.full((48, 64, 3), 20 * k, dtype=np.uint8) for k in range(12)]
    imageio.mimwrite(out / "video.mp4", frames, fps=12, macro_block_size=16)
    return metrics


def make_tiny_sweep(root: Path) -> Path:
    """Two gravity_sag variants (~1.5 s CPU) through the CLI; returns the results folder."""
    spec = root / "tiny.toml"
    spec.write_text(TINY_SWEEP)
    out = root / "sweep"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    return out


def records(sweep: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((sweep / "records").glob("*.json"))]
