"""CPU cost of the twist DoF: the dual-arm scene with hinge_pair (twist-rigid) vs hinge_triple joints.

The scenario's model options (timestep, dense Jacobian), 10 segments per section, a
ball central joint (the geometry that has a twist spring), both arms bent and held by
their pre-tensioned cables, the spindle running. CPU time (``time.thread_time``) per
step: the minimum over ``--repeats`` blocks of ``--steps`` steps after a warm-up, the two
joint kinds interleaved so machine load hits both alike. Prints JSON.

    python benchmarks/twist_step.py [--steps 1000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from continuum_sim import cable_lengths  # noqa: E402
from continuum_sim.glbackend import choose_gl_backend  # noqa: E402
from continuum_sim.model.options import model_geometry  # noqa: E402
from continuum_sim.model.scene import build_scene  # noqa: E402
from continuum_sim.model.state import set_arm_configuration  # noqa: E402
from continuum_sim.scenario.config import ScenarioConfig  # noqa: E402

choose_gl_backend()
import mujoco  # noqa: E402

POSES = {"left": np.radians([30, 180, 25, 150, 20, 210]), "right": np.radians([30, 0, 25, 30, 20, 330])}
PRETENSION = 10.0  # N


def _setup(joint: str):
    config = ScenarioConfig.default()
    geometry = dataclasses.replace(config.arm, central_joint="ball")
    options = dataclasses.replace(config.model, joint=joint)
    root = build_scene(geometry, config.layout, options)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    data = mujoco.MjData(model)
    geom = model_geometry(geometry, options)
    for arm, q in POSES.items():
        set_arm_configuration(model, data, geom, arm, q, joint)
        ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{arm}/cable_{k}_{c}") for k in range(3) for c in range(3)]
        data.ctrl[ids] = cable_lengths(geom, q) - PRETENSION / options.cable_kp
    mujoco.mj_forward(model, data)
    for _ in range(300):
        mujoco.mj_step(model, data)
    return model, data


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    cases = {joint: _setup(joint) for joint in ("hinge_pair", "hinge_triple")}
    blocks: dict[str, list[float]] = {joint: [] for joint in cases}
    for _ in range(args.repeats):
        for joint, (model, data) in cases.items():
            t0 = time.thread_time()
            for _ in range(args.steps):
                mujoco.mj_step(model, data)
            blocks[joint].append((time.thread_time() - t0) / args.steps)
    results = {}
    for joint, (model, data) in cases.items():
        results[joint] = {
            "nv": model.nv,
            "us_per_step_cpu": round(min(blocks[joint]) * 1e6, 1),
            "nefc": int(data.nefc),
            "warnings": int(sum(w.number for w in data.warning)),
        }
    ratio = results["hinge_triple"]["us_per_step_cpu"] / results["hinge_pair"]["us_per_step_cpu"]
    print(json.dumps({"benchmark": "twist DoF step cost (CPU time)", "results": results, "triple_over_pair": round(ratio, 3)}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
