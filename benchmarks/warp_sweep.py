"""The scenario's physics batched on MuJoCo Warp across hinge-stiffness variants, against CPU
``mujoco.rollout`` in the same run.

Each variant is the default scene with ``model.stiffness_scale`` set; the same-structure
variants differ only in ``jnt_stiffness`` (and ``jnt_damping``), so one compiled model serves
them all: on the GPU as per-world model fields, on the CPU as one ``mujoco.rollout`` call
over a list of models. Every world starts in the plan's first configuration with the
cables at their set-points and is stepped for ``--seconds`` under gravity (the arms settle
into their sag: the quantity the stiffness sweep is about). Reported: worlds/s and
steps/s on both, and the agreement of the final tool positions between GPU and CPU.

Needs an NVIDIA GPU and the optional extra ``pip install -e .[warp]`` (``mujoco-warp``).
Where either is missing it says so and exits 0: the CPU half alone is not the benchmark.

    python benchmarks/warp_sweep.py [--variants 8] [--worlds-per-variant 64] [--seconds 1.0]
        [--out benchmarks/warp_sweep.json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Any

import numpy as np

from continuum_sim.glbackend import choose_gl_backend

choose_gl_backend()

import mujoco  # noqa: E402
from mujoco import rollout  # noqa: E402

from continuum_sim.configio import replace_path  # noqa: E402
from continuum_sim.scenario.config import ScenarioConfig  # noqa: E402
from continuum_sim.scenario.runner import build_scene_model  # noqa: E402


def gpu_available() -> str | None:
    """None when MuJoCo Warp can run here, else why not (one line)."""
    try:
        import warp as wp

        import mujoco_warp  # noqa: F401
    except ImportError as exc:
        return f"mujoco-warp is not installed ({exc.name}); install the optional extra: pip install -e .[warp]"
    try:
        wp.init()
        if wp.get_cuda_device_count() == 0:
            return "no CUDA device: MuJoCo Warp needs an NVIDIA GPU"
    except Exception as exc:  # noqa: BLE001 - any driver failure means "no GPU here"
        return f"CUDA is not usable here ({type(exc).__name__}: {exc})"
    return None


def variant_models(scales: np.ndarray) -> list[mujoco.MjModel]:
    """One compiled scene per stiffness scale (same structure: only joint parameters differ)."""
    models = []
    for scale in scales:
        config = replace_path(ScenarioConfig.default(), "model.stiffness_scale", float(scale))
        models.append(build_scene_model(config)[1])
    return models


def initial_state(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """(full physics state, controls): the scene's rest pose with every cable at its mid set-point."""
    data = mujoco.MjData(model)
    data.ctrl[:] = model.actuator_ctrlrange.mean(axis=1)
    mujoco.mj_forward(model, data)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    return state, data.ctrl.copy()


def cpu_rollout(models: list[mujoco.MjModel], worlds: int, nstep: int) -> dict[str, Any]:
    state0, ctrl0 = initial_state(models[0])
    model_list = [m for m in models for _ in range(worlds)]
    states = np.tile(state0, (len(model_list), 1))
    controls = np.tile(ctrl0, (len(model_list), nstep, 1))
    datas = [mujoco.MjData(models[0]) for _ in range(os.cpu_count() or 1)]
    start = time.perf_counter()
    state_out, _ = rollout.rollout(model_list, datas, states, controls)
    wall = time.perf_counter() - start
    return {"wall_s": wall, "final_state": state_out[:, -1, :]}


def gpu_batch(models: list[mujoco.MjModel], worlds: int, nstep: int) -> dict[str, Any]:
    import warp as wp

    import mujoco_warp as mjw

    base = models[0]
    state0, ctrl0 = initial_state(base)
    data0 = mujoco.MjData(base)
    mujoco.mj_setState(base, data0, state0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    data0.ctrl[:] = ctrl0
    mujoco.mj_forward(base, data0)
    nworld = len(models) * worlds
    # Per-world model fields: the only ones a stiffness variant changes.
    m = mjw.put_model(base, batch_sizes={"jnt_stiffness": nworld, "dof_damping": nworld})
    m.jnt_stiffness.assign(np.repeat(np.stack([mm.jnt_stiffness for mm in models]), worlds, axis=0))
    m.dof_damping.assign(np.repeat(np.stack([mm.dof_damping for mm in models]), worlds, axis=0))
    d = mjw.put_data(base, data0, nworld=nworld)
    mjw.step(m, d)  # compile the kernels before timing
    wp.synchronize()
    d = mjw.put_data(base, data0, nworld=nworld)
    start = time.perf_counter()
    for _ in range(nstep):
        mjw.step(m, d)
    wp.synchronize()
    wall = time.perf_counter() - start
    return {"wall_s": wall, "qpos": d.qpos.numpy()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", type=int, default=8)
    parser.add_argument("--worlds-per-variant", type=int, default=64)
    parser.add_argument("--seconds", type=float, default=1.0)
    parser.add_argument("--out", help="also write the JSON here")
    args = parser.parse_args()
    why_not = gpu_available()
    if why_not is not None:
        print(f"warp_sweep: not run: {why_not}")
        return 0
    scales = np.geomspace(0.5, 8.0, args.variants)
    models = variant_models(scales)
    nstep = int(round(args.seconds / models[0].opt.timestep))
    nworld = args.variants * args.worlds_per_variant
    gpu = gpu_batch(models, args.worlds_per_variant, nstep)
    cpu_worlds = max(1, min(args.worlds_per_variant, 4))  # the CPU does a few worlds per variant
    cpu = cpu_rollout(models, cpu_worlds, nstep)
    nq = models[0].nq
    cpu_qpos = cpu["final_state"][::cpu_worlds, 1 : 1 + nq]  # mjSTATE_FULLPHYSICS: time, qpos, …
    gpu_qpos = gpu["qpos"][:: args.worlds_per_variant]
    out = {
        "variants": args.variants,
        "stiffness_scales": scales.round(4).tolist(),
        "steps": nstep,
        "gpu": {"worlds": nworld, "simulated_world_seconds_per_s": nworld * args.seconds / gpu["wall_s"],
                "steps_per_s": nworld * nstep / gpu["wall_s"]},
        "cpu_rollout": {"worlds": args.variants * cpu_worlds, "threads": os.cpu_count(),
                        "simulated_world_seconds_per_s": args.variants * cpu_worlds * args.seconds / cpu["wall_s"],
                        "steps_per_s": args.variants * cpu_worlds * nstep / cpu["wall_s"]},
        "agreement_max_abs_qpos": float(np.max(np.abs(cpu_qpos - gpu_qpos))),
    }
    out["gpu_over_cpu_steps_per_s"] = out["gpu"]["steps_per_s"] / out["cpu_rollout"]["steps_per_s"]
    text = json.dumps(out, indent=2)
    print(text)
    if args.out:
        with open(args.out, "w") as fh:
            fh.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
