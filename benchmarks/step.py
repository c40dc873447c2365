"""Step speed of the default dual-arm scene: µs per step and real-time factor (JSON).

Sweeps segments per section (5/10/20), joint kind (ball, hinge_pair) and tendons
(on/off) in one run. Each variant starts in the same bent pose; with tendons the cable
motors hold it (pre-tensioned), without tendons the flexure springs relax it. The
spindle runs. Timing is the median of ``--repeats`` blocks of ``--steps`` steps after a
warm-up, single thread.

    python benchmarks/step.py [--steps 1000] [--repeats 3] [--segments 5 10 20]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from continuum_sim import ArmGeometry, cable_lengths  # noqa: E402
from continuum_sim.layout import TaskLayout  # noqa: E402
from continuum_sim.model.options import ModelOptions, model_geometry  # noqa: E402
from continuum_sim.model.scene import build_scene  # noqa: E402
from continuum_sim.model.state import set_arm_configuration  # noqa: E402
from continuum_sim.model.tools import ToolOptions  # noqa: E402

# Both arms bent outward, away from each other and the plate, so no variant collides.
POSES = {"left": np.radians([30, 180, 25, 150, 20, 210]), "right": np.radians([30, 0, 25, 30, 20, 330])}
PRETENSION = 10.0  # N


def measure(options: ModelOptions, steps: int, repeats: int) -> dict:
    geometry = ArmGeometry.default()
    root = build_scene(geometry, TaskLayout(), options)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    data = mujoco.MjData(model)
    geom = model_geometry(geometry, options)
    for arm, q in POSES.items():
        set_arm_configuration(model, data, geom, arm, q, options.joint)
        if options.tendons:
            ids = [model.actuator(n).id for n in geom.cable_names(arm)]
            data.ctrl[ids] = cable_lengths(geom, q) - PRETENSION / options.cable_kp
    data.ctrl[model.actuator("left/grinder/spindle").id] = ToolOptions().spindle_speed
    mujoco.mj_forward(model, data)
    for _ in range(200):
        mujoco.mj_step(model, data)
    blocks = []
    ncon = nefc = 0
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(model, data)
        blocks.append((time.perf_counter() - t0) / steps)
        ncon += data.ncon
        nefc += data.nefc
    per_step = float(np.median(blocks))
    warnings = int(sum(w.number for w in data.warning))
    return {
        "segments_per_section": geom.sections[0].n_segments,
        "joint": options.joint,
        "tendons": options.tendons,
        "nq": model.nq,
        "nv": model.nv,
        "ntendon": model.ntendon,
        "nu": model.nu,
        "nefc_mean": round(nefc / repeats, 1),
        "us_per_step": round(per_step * 1e6, 1),
        "realtime_factor": round(model.opt.timestep / per_step, 2),
        "warnings": warnings,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--segments", type=int, nargs="+", default=[5, 10, 20])
    args = parser.parse_args(argv)
    results = []
    for n in args.segments:
        for joint in ("ball", "hinge_pair"):
            for tendons in (True, False):
                options = ModelOptions(segments_per_section=n, joint=joint, tendons=tendons)
                results.append(measure(options, args.steps, args.repeats))
    out = {
        "benchmark": "dual-arm scene mj_step",
        "timestep_s": ModelOptions().timestep,
        "integrator": ModelOptions().integrator,
        "steps_per_block": args.steps,
        "repeats": args.repeats,
        "mujoco": mujoco.__version__,
        "machine": {"platform": platform.platform(), "processor": platform.processor(), "cpus": os.cpu_count()},
        "results": results,
    }
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
