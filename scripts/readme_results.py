"""The README's results table and picture: the default task closed vs open loop, CPU time, one frame.

    python scripts/readme_results.py [--out runs/readme] [--frame docs/run_frame.png] [--frame-only]

Runs the shipped default scenario twice (control.mode closed, then open), prints a Markdown
table of the task metrics and the CPU time (time.process_time) per simulated second, and
renders one frame of the closed-loop run mid-cut as the video draws it (an observer grabs it:
no video needed; ``--frame-only`` renders just the frame).
"""

from __future__ import annotations

import argparse
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="runs/readme")
    parser.add_argument("--frame", default="docs/run_frame.png")
    parser.add_argument("--frame-only", action="store_true", help="only the frame (the closed-loop run up to the cut's end)")
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
