"""Scenario speed in CPU time: real-time factor of the whole run without video, configurations
compared interleaved in one process, and the video recorder against a bare renderer.

These machines are shared: wall time says more about the neighbours than about the code
(one run took 14 s wall at load 5 and 6.7 s at load 1.6). So the figure of merit is CPU
time of this process (``time.process_time``: the physics is single-threaded), every
configuration is run ``--repeat`` times *interleaved* (A B A B …, so a change of load hits
all of them alike), the minimum over repeats is reported, and the load average seen is
printed with the result.

* ``scenario``: for each configuration (``--config NAME=PATH=VALUE[,PATH=VALUE]``; the
  default configuration is always ``default``): CPU seconds and ``cpu_real_time_factor``
  (simulated s / CPU s) of the whole run (plan, build, control, cutting, records,
  metrics), the time inside ``mj_step`` and the task metrics; ratios against ``default``
  and whether the task metrics are identical to it.
  ``plain_cable_path`` (``model.cable_path = "spatial"``, MuJoCo's own tendons) is always run
  beside ``default`` (the native cable path): ``fast_vs_plain_cable_path`` gives their CPU
  ratio and how far their task metrics are apart (the paths agree to round-off per step,
  so the metrics agree to ~1e-10 relative, not bit for bit).
* ``bare_mj_step``: plain ``mj_step`` of the same scene for the same simulated time (both paths);
  ``run_vs_bare_mj_step`` is the default run's speed over bare ``mj_step``'s (bare CPU s / run CPU s),
  a ratio that depends less on the machine than either figure. ``machine.cpu_model`` names the CPU.
* ``video`` (``--frames N``, 0 skips it): the run's ``VideoRecorder`` (parallel render
  workers, drawing a mid-cut kerf's voxels and the overlay as a run's video does; and
  without them, ``recorder_plain``) against a bare in-process ``mujoco.Renderer`` rendering
  the same cameras at the same size and tessellation, wall time (the recorder spreads over
  processes); the kerf's and the overlay's CPU time per frame.

    python benchmarks/scenario.py [--repeat 3] [--stages initial,clamping] [--frames 60]
        [--config stiff=model.stiffness_scale=2] [--out benchmarks/scenario.json]
    python benchmarks/scenario.py --video-only --frames 300 --out benchmarks/video.json
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from continuum_sim.glbackend import choose_gl_backend

choose_gl_backend()

import mujoco  # noqa: E402

from continuum_sim.configio import replace_path  # noqa: E402
from continuum_sim.plant.cable_path import make_data  # noqa: E402
from continuum_sim.provenance import _cpu_model  # noqa: E402
from continuum_sim.scenario.config import ScenarioConfig  # noqa: E402
from continuum_sim.scenario.metrics import WALL_CLOCK_METRICS  # noqa: E402
from continuum_sim.scenario.runner import build_run_model, build_scene_model, run_scenario  # noqa: E402
from continuum_sim.video import VideoRecorder  # noqa: E402
from continuum_sim.video import _prepare_model as prepare_video_model  # noqa: E402

GOAL_CPU_REAL_TIME_FACTOR = 12.0
FLOOR_CPU_REAL_TIME_FACTOR = 10.0
PLAIN = "plain_cable_path"  # model.cable_path = "spatial": MuJoCo's own spatial tendons


def _task_metrics(metrics: dict[str, Any]) -> dict[str, Any]:
    """The metrics a run computes from its physics (wall-clock keys dropped)."""
    return {k: v for k, v in metrics.items() if k not in WALL_CLOCK_METRICS}


def _config_variant(spec: str) -> tuple[str, ScenarioConfig]:
    """``NAME=PATH=VALUE[,PATH=VALUE…]`` -> (name, the default config with those values)."""
    name, _, assignments = spec.partition("=")
    config = ScenarioConfig.default()
    for item in filter(None, assignments.split(",")):
        path, _, raw = item.partition("=")
        try:
            value: Any = json.loads(raw)
        except json.JSONDecodeError:
            value = raw.strip()
        config = replace_path(config, path.strip(), value)
    return name, config


def _leaves(value: Any, prefix: str = "") -> dict[str, Any]:
    """Flattened metrics: dotted key -> leaf value."""
    if isinstance(value, (dict, list, tuple)):
        out: dict[str, Any] = {}
        for k, v in (value.items() if isinstance(value, dict) else enumerate(value)):
            out.update(_leaves(v, f"{prefix}{k}."))
        return out
    return {prefix.rstrip("."): value}


def max_relative_difference(a: dict[str, Any], b: dict[str, Any]) -> float:
    """Largest |x − y| / max(|y|, 1e-6) over the numeric leaves of two metric trees (inf if a
    non-numeric leaf or the key set differs; values below 1e-6 in their unit count as round-off): how far two paths' task metrics are apart."""
    la, lb = _leaves(a), _leaves(b)
    if la.keys() != lb.keys():
        return float("inf")
    worst = 0.0
    for key, x in la.items():
        y = lb[key]
        if isinstance(x, bool) or isinstance(y, bool) or not isinstance(x, (int, float)) or not isinstance(y, (int, float)):
            if x != y:
                return float("inf")
            continue
        if x != y:
            worst = max(worst, abs(x - y) / max(abs(y), 1e-6))
    return worst


def bare_stepping(model: mujoco.MjModel, seconds: float) -> float:
    """CPU seconds of plain mj_step for ``seconds`` of simulated time (cables held)."""
    data = make_data(model)  # registered with the native cable path when the model has one
    data.ctrl[:] = model.actuator_ctrlrange.mean(axis=1)
    mujoco.mj_forward(model, data)
    start = time.process_time()
    mujoco.mj_step(model, data, nstep=int(round(seconds / model.opt.timestep)))
    return time.process_time() - start


def run_once(config: ScenarioConfig, stages: tuple[str, ...] | None) -> dict[str, Any]:
    cpu0, wall0 = time.process_time(), time.perf_counter()
    metrics = run_scenario(config, None, stages=stages)
    return {"cpu_s": time.process_time() - cpu0, "wall_s": time.perf_counter() - wall0, "metrics": metrics}


def _half_cut_grid(config: ScenarioConfig, model: Any, data: Any) -> Any:
    """The cutter's voxel grid of the scene with the first half of the kerf cleared (what a
    mid-cut frame draws: the most boxes, the uncut band being two)."""
    import numpy as np

    from continuum_sim.plant.cutter import foam_cutter

    grid = foam_cutter(model, data, config.layout, config.scene).grid
    plate = config.layout.plate
    line, w = plate.kerf_polyline(), plate.kerf_width / 2
    gx, gy = np.meshgrid(grid.centres[0], grid.centres[1], indexing="ij")
    grid.material[(np.abs(gx - line[0, 0]) <= w) & (gy <= line[1, 1])] = False  # the first leg
    grid.material[(np.abs(gy - line[1, 1]) <= w) & (gx <= (line[1, 0] + line[2, 0]) / 2), 4:] = False  # half the second, top
    return grid


def _record(model: Any, config: ScenarioConfig, data: Any, frames: int, grid: Any, text: tuple[str, ...]) -> tuple[float, int]:
    sim = config.simulation
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        with VideoRecorder(model, Path(tmp) / "v.mp4", sim.cameras, sim.video_width, sim.video_height, sim.video_fps,
                           sim.video_shadows, grid=grid) as video:
            for _ in range(frames):
                video.next_time = data.time
                video.maybe_capture(data, text)
        return time.perf_counter() - start, video.workers  # includes worker start-up and the final join


def video_comparison(config: ScenarioConfig, frames: int) -> dict[str, Any]:
    """Wall time of the recorder (workers) and of a bare in-process renderer on the same frames.

    The recorder draws what a run's video draws mid-cut (the kerf's voxels, the overlay text);
    ``recorder_plain`` is the recorder without them (the video before issue 25). The CPU cost
    of the kerf boxes and the overlay per frame is timed in-process (``time.process_time``)."""
    import numpy as np

    from continuum_sim.video_foam import KerfVoxels
    from continuum_sim.video_overlay import draw_overlay

    sim = config.simulation
    _, model = build_scene_model(config)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    grid = _half_cut_grid(config, model, data)
    text = ("t  24.0 s   milling", "cut  50 %   sample held by the plate", "spindle   9549 rpm   force 0.044 N")
    recorder_wall, workers = _record(model, config, data, frames, grid, text)
    plain_wall, _ = _record(model, config, data, frames, None, ())
    prepare_video_model(model, sim.video_width, sim.video_height, sim.video_shadows, "fast")  # as the recorder's workers do
    kerf = KerfVoxels.from_model(model, grid)
    assert kerf is not None
    packed = kerf.snapshot(grid.material)
    with mujoco.Renderer(model, sim.video_height, sim.video_width) as renderer:
        start = time.perf_counter()
        for _ in range(frames):
            for name in sim.cameras:
                renderer.update_scene(data, camera=name)
                renderer.render()
        bare_wall = time.perf_counter() - start
        cpu0 = time.process_time()
        for _ in range(frames):
            boxes = kerf.boxes(packed)
            for name in sim.cameras:
                renderer.update_scene(data, camera=name)
                kerf.add_to_scene(renderer.scene, boxes)
        kerf_cpu = time.process_time() - cpu0
        cpu0 = time.process_time()
        frame = np.zeros((sim.video_height, sim.video_width * len(sim.cameras), 3), np.uint8)
        for _ in range(frames):
            draw_overlay(frame, text, sim.video_height)
        overlay_cpu = time.process_time() - cpu0
    return {
        "cameras": list(sim.cameras),
        "size": [sim.video_width, sim.video_height],
        "frames": frames,
        "workers": workers,
        "kerf_boxes_mid_cut": len(kerf.boxes(packed)),
        "recorder_fps_wall": round(frames / recorder_wall, 2),
        "recorder_plain_fps_wall": round(frames / plain_wall, 2),
        "bare_renderer_fps_wall": round(frames / bare_wall, 2),
        "ratio": round(bare_wall / recorder_wall, 3),
        "ratio_plain": round(bare_wall / plain_wall, 3),
        "kerf_ms_cpu_per_frame": round(1000 * kerf_cpu / frames, 3),
        "overlay_ms_cpu_per_frame": round(1000 * overlay_cpu / frames, 3),
        "goal_ratio": 0.8,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stages", default="", help="comma-separated stages (default: the whole task)")
    parser.add_argument("--repeat", type=int, default=3, help="interleaved repeats of every configuration")
    parser.add_argument("--config", action="append", default=[], help="NAME=PATH=VALUE[,PATH=VALUE]: a configuration to compare")
    parser.add_argument("--frames", type=int, default=60, help="video frames to time (0: skip)")
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    parser.add_argument("--video-only", action="store_true", help="only the video comparison (--frames)")
    args = parser.parse_args()
    if args.video_only:
        load = os.getloadavg()
        video = video_comparison(ScenarioConfig.default(), args.frames)
        text = json.dumps({"measured": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
                           "machine": {"cpu_model": _cpu_model(), "cpus": os.cpu_count(),
                                       "load_avg_1_5_15_before": [round(x, 2) for x in load],
                                       "load_avg_1_5_15_after": [round(x, 2) for x in os.getloadavg()]},
                           "video": video}, indent=2)
        print(text)
        if args.out is not None:
            args.out.write_text(text + "\n")
        return
    stages = tuple(s for s in args.stages.split(",") if s) or None
    # The plain MuJoCo path (spatial tendons) is always measured beside the default (native) one.
    plain = _config_variant(f"{PLAIN}=model.cable_path=spatial")
    configs = dict([("default", ScenarioConfig.default()), plain] + [_config_variant(spec) for spec in args.config])

    load_before = os.getloadavg()
    runs: dict[str, list[dict[str, Any]]] = {name: [] for name in configs}
    for _ in range(args.repeat):
        for name, config in configs.items():  # interleaved: A B A B …
            runs[name].append(run_once(config, stages))
    load_after = os.getloadavg()

    reference = _task_metrics(runs["default"][0]["metrics"])
    scenario: dict[str, Any] = {}
    for name, results in runs.items():
        sim_seconds = results[0]["metrics"]["sim_seconds"]
        cpu = [r["cpu_s"] for r in results]
        physics = [r["metrics"]["wall_breakdown_s"]["physics_mj_step"] for r in results]
        first = _task_metrics(results[0]["metrics"])
        scenario[name] = {
            "sim_seconds": round(sim_seconds, 3),
            "cpu_seconds_min": round(min(cpu), 3),
            "cpu_seconds_median": round(statistics.median(cpu), 3),
            "cpu_real_time_factor": round(sim_seconds / min(cpu), 3),
            "wall_seconds_min": round(min(r["wall_s"] for r in results), 3),
            "mj_step_real_time_factor": round(sim_seconds / min(physics), 3),
            "repeat_identical": all(_task_metrics(r["metrics"]) == first for r in results),
            "task_metrics_identical_to_default": first == reference,
            "task_metrics_max_relative_difference_vs_default": max_relative_difference(first, reference),
            "cpu_ratio_vs_default": round(min(cpu) / min(r["cpu_s"] for r in runs["default"]), 3),
            "task_outcome_identical_to_default": results[0]["metrics"].get("task") == runs["default"][0]["metrics"].get("task"),
            "cutting_tip_error_mm": results[0]["metrics"].get("cutting_tip_error_mm"),
            "sample_detached": results[0]["metrics"].get("sample_detached"),
        }
    _, model, _ = build_run_model(configs["default"])
    bare = bare_stepping(model, scenario["default"]["sim_seconds"])
    _, plain_model = build_scene_model(configs["default"])
    bare_plain = bare_stepping(plain_model, scenario["default"]["sim_seconds"])
    out: dict[str, Any] = {
        "measured": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
        "machine": {"cpu_model": _cpu_model(), "cpus": os.cpu_count(),
                    "load_avg_1_5_15_before": [round(x, 2) for x in load_before],
                    "load_avg_1_5_15_after": [round(x, 2) for x in load_after]},
        "stages": list(stages) if stages else "all",
        "repeat": args.repeat,
        "timestep_s": model.opt.timestep,
        "goal_cpu_real_time_factor": GOAL_CPU_REAL_TIME_FACTOR,
        "floor_cpu_real_time_factor": FLOOR_CPU_REAL_TIME_FACTOR,
        "cpu_real_time_factor": scenario["default"]["cpu_real_time_factor"],
        "scenario": scenario,
        "bare_mj_step_cpu_seconds": round(bare, 3),
        "bare_mj_step_cpu_real_time_factor": round(scenario["default"]["sim_seconds"] / bare, 3),
        # the whole run's speed as a share of bare mj_step's on the same scene (1 = nothing but mj_step)
        "run_vs_bare_mj_step": round(bare / scenario["default"]["cpu_seconds_min"], 3),
        "bare_mj_step_plain_cable_path_cpu_real_time_factor": round(scenario["default"]["sim_seconds"] / bare_plain, 3),
        "fast_vs_plain_cable_path": {
            "cpu_ratio": scenario[PLAIN]["cpu_ratio_vs_default"],
            "task_outcome_identical": scenario[PLAIN]["task_outcome_identical_to_default"],
            "task_metrics_max_relative_difference": scenario[PLAIN]["task_metrics_max_relative_difference_vs_default"],
        },
    }
    if args.frames > 0:
        out["video"] = video_comparison(configs["default"], args.frames)
    text = json.dumps(out, indent=2)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
