"""The README's results table and picture: the default task closed vs open loop, CPU time, one frame.

    python scripts/readme_results.py [--out runs/readme] [--frame docs/run_frame.png]

Runs the shipped default scenario twice (control.mode closed, then open), prints a Markdown
table of the task metrics and the CPU time (time.process_time) per simulated second, and
renders one frame of the closed-loop run mid-cut (an observer grabs it: no video needed).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from continuum_sim.scenario.config import ScenarioConfig, merged
from continuum_sim.scenario.runner import run_scenario
from continuum_sim.scenario.simulate import Observer, Simulation


class FrameGrab(Observer):
    """Renders one frame from the first configured camera the first tick the grinder is cutting."""

    def __init__(self, path: Path, camera: str, width: int = 960, height: int = 540) -> None:
        self.path, self.camera, self.size = path, camera, (height, width)
        self.done = False

    def after_tick(self, sim: Simulation) -> str | None:
        if self.done or not sim.plan.cutting[sim.plan_index] or sim.plan_index < np.flatnonzero(sim.plan.cutting).mean():
            return None
        import imageio.v2 as imageio
        import mujoco

        from continuum_sim.video import pose_for_drawing

        model = sim.drawable_model  # draws the cables (a native-cable run simulates fixed tendons)
        data, d = mujoco.MjData(model), sim.data
        pose_for_drawing(model, data, d.time, d.qpos, d.mocap_pos, d.mocap_quat, sim.model.geom_rgba)
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, self.size[1])
        model.vis.global_.offheight = max(model.vis.global_.offheight, self.size[0])
        with mujoco.Renderer(model, *self.size) as renderer:
            renderer.update_scene(data, camera=self.camera)
            imageio.imwrite(self.path, renderer.render())
        self.done = True
        return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="runs/readme")
    parser.add_argument("--frame", default="docs/run_frame.png")
    args = parser.parse_args()
    rows = []
    for mode in ("closed", "open"):
        config = merged(ScenarioConfig.default(), {"control": {"mode": mode}})
        hooks = [FrameGrab(Path(args.frame), config.simulation.cameras[0])] if mode == "closed" else []
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
