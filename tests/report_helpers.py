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


PROVENANCE = {
    "schema": 1, "command": "run", "argv": ["continuum-sim", "run", "--out", "runs/x"], "created_utc": "2025-01-01T00:00:00Z",
    "package": {"name": "continuum-sim", "version": "0.1.0"},
    "git": {"commit": "0123456789abcdef0123456789abcdef01234567", "dirty": True, "changed": ["continuum_sim/report/run.py"]},
    "code_sha256": "c0de" * 16, "hashes": {"config": "aa" * 32, "registry": "bb" * 32, "spec": None},
    "versions": {"python": "3.12.0", "mujoco": "3.17.0", "numba": "0.60", "numpy": "2.0", "scipy": "1.14", "SALib": "1.5",
                 "optuna": "4.0", "dm_control": None},
    "machine": {"platform": "Linux-x86_64", "cpu": "x86_64", "cpu_count": 2, "threads": {"OMP_NUM_THREADS": "1"}},
}


def make_fake_run(out: Path, frames: int = 12) -> Path:
    """A run folder built without simulating: config.toml and parameters.json from the real registry (seed and
    cable friction overridden), a minimal metrics.json and a ``frames``-frame video.mp4 whose frame k is grey 20 k."""
    import imageio.v2 as imageio

    from continuum_sim.params.registry import apply
    from continuum_sim.scenario.runner import write_parameters

    out.mkdir(parents=True)
    config = apply(merged(ScenarioConfig.default(), {"simulation": {"seed": SEED}}), {"model.cable_friction.mu": 0.2})
    config.save_toml(out / "config.toml")
    write_parameters(out, config)
    (out / "metrics.json").write_text(json.dumps({"status": "complete", "task": {"completed": True, "failure": None},
                                                 "sim_seconds": 1.0, "control": "open"}))
    video = [np.full((48, 64, 3), 20 * k, dtype=np.uint8) for k in range(frames)]
    imageio.mimwrite(out / "video.mp4", video, fps=12, macro_block_size=16)
    return out


def make_tiny_sweep(root: Path) -> Path:
    """Two gravity_sag variants (~1.5 s CPU) through the CLI; returns the results folder."""
    spec = root / "tiny.toml"
    spec.write_text(TINY_SWEEP)
    out = root / "sweep"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    return out


def records(sweep: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((sweep / "records").glob("*.json"))]
