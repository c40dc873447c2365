"""The README's results table and picture: the default task closed vs open loop, CPU time, one frame.

    python scripts/readme_results.py [--out runs/readme] [--frame docs/run_frame.png] [--frame-only]

Runs the shipped default scenario twice (control.mode closed, then open), prints a Markdown
table of the task metrics and the CPU time (time.process_time) per simulated second, and
renders one frame of the closed-loop run mid-cut as the video draws it (an observer grabs it:
no video needed; ``--frame-only`` renders just the frame).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from continuum_sim.scenario.config import ScenarioConfig, merged
from continuum_sim.scenario.runner import run_scenario
from continuum_sim.scenario.simulate import Observer, Simulation
from continuum_sim.scenario.video_observer import overlay_text


class FrameGrab(Observer):
    """Renders one video frame (both cameras, the kerf as cut, the overlay: what ``run --video``
    draws) the first tick the grinder is cutting past the middle of the cut."""

    def __init__(self, path: Path, config: ScenarioConfig) -> None:
        self.path, self.sim_config = path, config.simulation
        self.done = False

    def after_tick(self, sim: Simulation) -> str | None:
        if self.done or not sim.plan.cutting[sim.plan_index] or sim.plan_index < np.flatnonzero(sim.plan.cutting).mean():
            return None
        import pickle
        import tempfile

        import imageio.v2 as imageio

        from continuum_sim.video import VideoRecorder

        c = self.sim_config
        model = pickle.loads(pickle.dumps(sim.drawable_model))  # draws the cables; the run's model stays untouched
        model.geom_rgba[:] = sim.model.geom_rgba
        with tempfile.TemporaryDirectory() as tmp:
            video = VideoRecorder(model, Path(tmp) / "frame.mp4", c.cameras, c.video_width, c.video_height,
                                  workers=0, grid=sim.cutter.grid)
            try:
                force = float(np.linalg.norm(sim.cutter.state.force))
                frame = video.render_frame(sim.data, overlay_text(sim, force) if c.video_overlay else ())
            finally:
                video.close(keep=False)
        imageio.imwrite(self.path, frame)
        self.done = True
        return None


KEYS = (
    "task", "cutting_tip_error_mm", "cut_path_deviation_mm", "spindle_axis_error_deg", "sample_detached", "sample_held_at_end",
    "detached_before_cut_complete", "detach_time_s", "min_arm_distance_m", "max_cable_tension_n", "min_cable_tension_n",
    "max_contact_force_n", "cells_remaining", "cells_total", "sim_seconds", "timestep_s",
)


def write_json(path: Path, rows: list[tuple[str, dict, float]]) -> None:
    """Both runs' key metrics (everything the docs quote from them), the clamping-stage gripper error, the kerf, provenance."""
    from continuum_sim.configio import atomic_write_text
    from continuum_sim.params.registry import registry_sha256
    from continuum_sim.provenance import collect

    doc: dict = {"provenance": collect("scripts/readme_results.py", config_toml=None, registry_sha256=registry_sha256(), spec_path=None)}
    for mode, m, cpu in rows:
        entry = {k: m[k] for k in KEYS if k in m}
        entry["tip_error_mm"] = m.get("tip_error_mm")
        entry["kerf"] = (m.get("cutting") or {}).get("kerf")
        entry["cutting_force_n"] = (m.get("cutting") or {}).get("force_n")
        entry["cpu_s"] = cpu
        doc[mode] = entry
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps(doc, indent=1, sort_keys=True, ensure_ascii=False) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="runs/readme")
    parser.add_argument("--frame", default="docs/run_frame.png")
    parser.add_argument("--frame-only", action="store_true", help="only the frame (the closed-loop run up to the cut's end)")
    parser.add_argument("--json", type=Path, help="also write both runs' key metrics here (the numbers the docs quote)")
    args = parser.parse_args()
    if args.frame_only:
        config = ScenarioConfig.default()
        run_scenario(config, None, stages=("initial", "clamping", "milling"), observers=[FrameGrab(Path(args.frame), config)])
        return
    rows = []
    for mode in ("closed", "open"):
        config = merged(ScenarioConfig.default(), {"control": {"mode": mode}})
        hooks = [FrameGrab(Path(args.frame), config)] if mode == "closed" else []
        start = time.process_time()
        m = run_scenario(config, Path(args.out) / mode, observers=hooks)
        cpu = time.process_time() - start
        rows.append((mode, m, cpu))
    if args.json:
        write_json(args.json, rows)
    print("| control | cutting error mean / max (mm) | cut path deviation max (mm) | spindle axis max (°) | "
          "sample cut free / held | min arm gap (mm) | CPU s per sim s |")
    print("|---|---|---|---|---|---|---|")
    for mode, m, cpu in rows:
        c = m["cutting_tip_error_mm"]
        print(f"| {mode} | {c['mean']:.2f} / {c['max']:.2f} | {m['cut_path_deviation_mm']['max']:.2f} | "
              f"{m['spindle_axis_error_deg']['max']:.2f} | {m['sample_detached']} / {m['sample_held_at_end']} | "
              f"{1000 * m['min_arm_distance_m']:.1f} | {cpu / m['sim_seconds']:.2f} |")


if __name__ == "__main__":
    main()
