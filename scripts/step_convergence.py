"""Step convergence of the default task: the same run at several ``model.timestep`` values.

    python scripts/step_convergence.py [--steps 0.001,0.002,0.004,0.008] [--control closed]

Prints, per step, the quantities a larger step would move first: the cutting error, the
gripper arm's tip error while the grasp closes (clamping) and while it holds the sample
during the cut (milling), the detach time and the CPU seconds of the run. The step a run
uses is the stable step (``model.stable_step``), which never enlarges the one asked for.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

from continuum_sim.glbackend import choose_gl_backend

choose_gl_backend()

from continuum_sim.scenario.config import ScenarioConfig  # noqa: E402
from continuum_sim.scenario.runner import run_scenario  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", default="0.001,0.002,0.004,0.008", help="comma-separated timesteps (s)")
    parser.add_argument("--control", choices=["closed", "open"], default="closed")
    args = parser.parse_args()
    base = ScenarioConfig.default()
    base = dataclasses.replace(base, control=dataclasses.replace(base.control, mode=args.control))
    rows = []
    for h in (float(x) for x in args.steps.split(",")):
        config = dataclasses.replace(base, model=dataclasses.replace(base.model, timestep=h))
        start = time.process_time()
        m = run_scenario(config, None)
        right = m["tip_error_mm"]["right"]
        rows.append({
            "timestep_s": m["timestep_s"],
            "completed": m["task"]["completed"],
            "cutting_error_mean_mm": round(m["cutting_tip_error_mm"]["mean"], 4),
            "gripper_clamping_max_mm": round(right["clamping"]["max"], 2),
            "gripper_milling_mean_mm": round(right["milling"]["mean"], 3),
            "detach_time_s": m["detach_time_s"],
            "cpu_s": round(time.process_time() - start, 2),
        })
        print(json.dumps(rows[-1]), flush=True)


if __name__ == "__main__":
    main()
