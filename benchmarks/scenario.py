"""Scenario speed: real-time factor without video, and video frames/s vs a bare renderer.

Prints JSON. Both comparisons run in this process, on the same compiled scene, so the
ratios hold on a noisy machine:

* ``scenario``: the whole sample-removal run (plan, control, cutting, recording) without
  video, against plain ``mj_step`` of the same model for the same simulated time, and
  split by the run's own wall-time breakdown (``physics_only_real_time_factor``: the
  time inside ``mj_step`` during the run, the ceiling if all the Python were free);
* ``video``: ``VideoRecorder`` (render every camera, tile, encode to MP4) against a bare
  ``mujoco.Renderer`` loop that renders the same cameras at the same size.

    python benchmarks/scenario.py [--stages initial,clamping] [--frames 60]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from continuum_sim.glbackend import choose_gl_backend

choose_gl_backend()

import mujoco  # noqa: E402

from continuum_sim.scenario.config import ScenarioConfig  # noqa: E402
from continuum_sim.scenario.runner import build_scene_model, run_scenario  # noqa: E402
from continuum_sim.video import VideoRecorder  # noqa: E402


def bare_stepping(model: mujoco.MjModel, seconds: float) -> float:
    """Wall seconds of plain mj_step for ``seconds`` of simulated time (cables held)."""
    data = mujoco.MjData(model)
    data.ctrl[:] = model.actuator_ctrlrange.mean(axis=1)
    mujoco.mj_forward(model, data)
    start = time.perf_counter()
    for _ in range(int(round(seconds / model.opt.timestep))):
        mujoco.mj_step(model, data)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stages", default="", help="comma-separated stages (default: the whole task)")
    parser.add_argument("--frames", type=int, default=60, help="video frames to time")
    args = parser.parse_args()
    config = ScenarioConfig.default()
    stages = tuple(s for s in args.stages.split(",") if s) or None

    start = time.perf_counter()
    metrics = run_scenario(config, None, stages=stages)
    run_wall = time.perf_counter() - start
    _, model = build_scene_model(config)
    step_wall = bare_stepping(model, metrics["sim_seconds"])

    sim = config.simulation
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with tempfile.TemporaryDirectory() as tmp:
        with VideoRecorder(model, Path(tmp) / "v.mp4", sim.cameras, sim.video_width, sim.video_height, sim.video_fps) as video:
            video.maybe_capture(data)  # warm-up: GL context, encoder start
            start = time.perf_counter()
            for _ in range(args.frames):
                video.next_time = data.time
                video.maybe_capture(data)
            video_wall = time.perf_counter() - start
    with mujoco.Renderer(model, sim.video_height, sim.video_width) as renderer:
        for name in sim.cameras:
            renderer.update_scene(data, camera=name)
            renderer.render()
        start = time.perf_counter()
        for _ in range(args.frames):
            for name in sim.cameras:
                renderer.update_scene(data, camera=name)
                renderer.render()
        bare_wall = time.perf_counter() - start

    breakdown = metrics["wall_breakdown_s"]
    video_fps = args.frames / video_wall
    bare_fps = args.frames / bare_wall
    print(
        json.dumps(
            {
                "scenario": {
                    "stages": list(stages) if stages else "all",
                    "sim_seconds": round(metrics["sim_seconds"], 3),
                    "wall_seconds": round(run_wall, 3),
                    "real_time_factor": round(metrics["sim_seconds"] / run_wall, 3),
                    # mj_step inside the run (contacts, grasp, cutting): the ceiling if all
                    # Python (plan, control, records) were free.
                    "physics_only_real_time_factor": round(metrics["sim_seconds"] / breakdown["physics_mj_step"], 3),
                    "wall_breakdown_s": {k: round(v, 3) for k, v in breakdown.items()},
                    # mj_step of the same scene with the arms held and nothing touching.
                    "bare_mj_step_real_time_factor": round(metrics["sim_seconds"] / step_wall, 3),
                    "overhead_vs_bare_stepping": round(run_wall / step_wall, 3),
                    "timestep_s": model.opt.timestep,
                    "goal_real_time_factor": 10.0,
                },
                "video": {
                    "cameras": list(sim.cameras),
                    "size": [sim.video_width, sim.video_height],
                    "frames": args.frames,
                    "recorder_fps": round(video_fps, 2),
                    "bare_renderer_fps": round(bare_fps, 2),
                    "ratio": round(video_fps / bare_fps, 3),
                    "goal_ratio": 0.8,
                },
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
