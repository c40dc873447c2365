"""Cable friction: per-step CPU cost, kernel compile cost, capstan check and the hysteresis loop.

Prints JSON and writes the hysteresis figure (``--plot``). Everything is CPU
time (``time.process_time``), single process:

* ``step``: the scenario's dual-arm scene (its model options), both arms bent and held by
  pre-tensioned cables, ``mj_step`` with and without friction, interleaved repeats (min);
* ``compile``: the first use of the numba kernels in a fresh process, with numba's cache
  cold (a temporary cache directory) and warm;
* ``capstan``: the proximal section pulled by a pure tension source to ~90°, anchor
  tension from the statics (spring torque at the last joint over MuJoCo's moment arm)
  against e^(−μθ);
* ``hysteresis``: the same section under a staircase of motor tension up and down
  (each level held to rest), bend vs tension for μ = 0 and the default μ;
* ``scenario``: the whole default task with μ = 0 and the default μ: CPU time (closed loop,
  repeated, interleaved) and the task metrics, closed and open loop (~1–2 min CPU).

    python benchmarks/friction.py [--skip step compile capstan hysteresis scenario] [--plot docs/friction/hysteresis.png]
        [--json docs/friction/friction.json] [--md docs/friction/friction.md]

``--json`` also writes the printed JSON to a file (with ``hysteresis.summary``: the bends at the
staircase's middle level, loading and unloading, and either side of the top reversal, with and
without friction); ``--md`` writes the capstan table (docs/friction.md quotes both).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import mujoco
import numpy as np

from continuum_sim import cable_lengths
from continuum_sim.model.friction_options import DEFAULT_MU, DEFAULT_PRESLIDING, CableFrictionConfig
from continuum_sim.model.options import model_geometry
from continuum_sim.model.state import set_arm_configuration
from continuum_sim.plant import friction as fr
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.validation.capstan import anchor_tension as _anchor_tension
from continuum_sim.validation.capstan import hold as _hold
from continuum_sim.validation.capstan import rig, tension_for_bend
from continuum_sim.validation.capstan import settle as _settle
from continuum_sim.validation.capstan import wrap_angle as _wrap

POSES = {"left": np.radians([30, 180, 25, 150, 20, 210]), "right": np.radians([30, 0, 25, 30, 20, 330])}
PRETENSION = 10.0  # N
CABLE = "arm/cable_0_0"
HYSTERESIS_MU = 0.15  # the loop plotted in docs/friction/hysteresis.png (printed-polymer holes)


# ----------------------------------------------------------------------------- step cost
def _held_scene(config: ScenarioConfig) -> tuple[mujoco.MjModel, mujoco.MjData]:
    from continuum_sim.model.scene import build_scene

    root = build_scene(config.arm, config.layout, config.model, config.scene)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    data = mujoco.MjData(model)
    geom = model_geometry(config.arm, config.model)
    for arm, q in POSES.items():
        set_arm_configuration(model, data, geom, arm, q, config.model.joint)
        ids = [model.actuator(n).id for n in geom.cable_names(arm)]
        data.ctrl[ids] = cable_lengths(geom, q) - PRETENSION / model.actuator_gainprm[ids, 0]
    mujoco.mj_forward(model, data)
    return model, data


def step_cost(steps: int, repeats: int) -> dict:
    config = ScenarioConfig()  # the dataclass defaults (= the shipped scenario.toml when it is fresh)
    model, base = _held_scene(config)
    for _ in range(200):
        mujoco.mj_step(model, base)
    plain = mujoco.MjData(model)
    rough = mujoco.MjData(model)
    for d in (plain, rough):
        mujoco.mj_copyData(d, model, base)
    handle = fr.install_cable_friction(model, rough, CableFrictionConfig())
    times: dict[str, list[float]] = {"without": [], "with": []}
    for _ in range(repeats):
        for key, d in (("without", plain), ("with", rough)):
            t0 = time.process_time()
            for _ in range(steps):
                mujoco.mj_step(model, d)
            times[key].append((time.process_time() - t0) / steps)
    handle.check()
    # the callback's own work, timed directly (same state)
    t0 = time.process_time()
    for _ in range(steps):
        handle.runtime.run(model, rough)
    callback = (time.process_time() - t0) / steps
    without, with_ = min(times["without"]), min(times["with"])
    return {
        "scene": "scenario dual-arm scene, arms bent and held",
        "joint": config.model.joint,
        "timestep_s": model.opt.timestep,
        "cables": len(handle.routing.cable_start),
        "pieces": handle.routing.n_pieces,
        "us_per_step_without": round(without * 1e6, 1),
        "us_per_step_with": round(with_ * 1e6, 1),
        "overhead_percent": round(100 * (with_ - without) / without, 1),
        "callback_us": round(callback * 1e6, 1),
        "anchor_ratio_range": [round(float(handle.anchor_ratio().min()), 4), round(float(handle.anchor_ratio().max()), 4)],
    }


def compile_cost() -> dict:
    code = (
        "import time;t=time.process_time();"
        "from continuum_sim.plant import friction as fr;import numpy as np;"
        "from continuum_sim.model.friction_options import CableFrictionConfig;"
        "from continuum_sim.model.arm import build_single_arm_model;from continuum_sim.geometry import ArmGeometry;"
        "from continuum_sim.model.options import ModelOptions;import mujoco;"
        "r=build_single_arm_model(ArmGeometry.default(),ModelOptions(joint='hinge_pair'));"
        "mm=mujoco.MjModel.from_xml_string(r.to_xml_string(),r.get_assets());dd=mujoco.MjData(mm);"
        "t=time.process_time();h=fr.install_cable_friction(mm,dd,CableFrictionConfig());mujoco.mj_forward(mm,dd);h.check();"
        "print(time.process_time()-t)"
    )
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("cold_cache_s", "warm_cache_s"):
            res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
            out[label] = round(float(res.stdout.strip().splitlines()[-1]), 3)
    return out


# ------------------------------------------------------------------------- section rig



def _bend(model, data, ten: int) -> float:
    adr, num = model.tendon_adr[ten], model.tendon_num[ten]
    body = model.site_bodyid[model.wrap_objid[adr + num - 1]]
    return float(np.degrees(np.arccos(np.clip(data.xmat[body].reshape(3, 3)[2, 2], -1.0, 1.0))))




def _fresh(model, mu: float):
    data = mujoco.MjData(model)
    data.ctrl[:] = model.actuator_ctrlrange[:, 1]
    return data, fr.install_cable_friction(model, data, CableFrictionConfig(mu=mu))



def capstan() -> list[dict]:
    model, act, ten = rig()
    rows = []
    for mu in (0.0, 0.1, 0.15, 0.2):
        T = tension_for_bend(model, ten, np.pi / 2)
        for _ in range(5):
            data, handle = _fresh(model, mu)
            _hold(model, data, act, 0.0, T, 250, 0)
            _settle(model, data, act, T)
            mujoco.mj_forward(model, data)
            wrap = _wrap(model, data, ten)
            if abs(np.degrees(wrap) - 90.0) < 0.5:
                break
            T *= (np.pi / 2) / wrap
        ratio = _anchor_tension(model, data, ten) / T
        rows.append(
            {
                "mu": mu,
                "motor_tension_n": round(T, 2),
                "wrap_deg": round(np.degrees(wrap), 2),
                "anchor_over_motor": round(ratio, 4),
                "max_qvel_at_measurement": float(np.abs(data.qvel).max()),
                "capstan_exp_minus_mu_theta": round(float(np.exp(-mu * wrap)), 4),
                "error_percent": round(100 * (ratio / np.exp(-mu * wrap) - 1), 2),
            }
        )
        handle.uninstall()
    return rows


def hysteresis(levels: int, hold: int) -> dict:
    model, act, ten = rig()
    top = tension_for_bend(model, ten, np.radians(85.0))
    up = np.linspace(0.0, top, levels + 1)
    path = np.r_[up, up[-2::-1]]
    out = {}
    for mu in (0.0, HYSTERESIS_MU):
        data, handle = _fresh(model, mu)
        bends, prev = [], 0.0
        for T in path:
            _hold(model, data, act, prev, T, 25, 0)
            _settle(model, data, act, T, hold)
            prev = T
            bends.append(_bend(model, data, ten))
        out[mu] = (path, np.array(bends))
        handle.uninstall()
    return out


def hysteresis_summary(loops: dict, levels: int) -> dict:
    """The bends the page quotes: at the middle level going up and coming down, and at the top
    level and the first level below it (the reversal), for μ = 0 and ``HYSTERESIS_MU``."""
    T = next(iter(loops.values()))[0]
    mid, top = levels // 2, levels
    out: dict = {"mu": HYSTERESIS_MU, "mid_tension_n": round(float(T[mid]), 2), "top_tension_n": round(float(T[top]), 2),
                 "after_top_tension_n": round(float(T[top + 1]), 2)}
    for name, mu in (("frictionless", 0.0), ("friction", HYSTERESIS_MU)):
        bend = loops[mu][1]
        out[name] = {"mid_loading_deg": round(float(bend[mid]), 1), "mid_unloading_deg": round(float(bend[2 * levels - mid]), 1),
                     "top_deg": round(float(bend[top]), 1), "after_top_deg": round(float(bend[top + 1]), 1)}
    return out


def capstan_table(rows: list[dict]) -> str:
    """The capstan check as a Markdown table (docs/friction.md)."""
    lines = ["| μ | motor T (N) | wrap | T_anchor/T_motor (model) | e^(−μθ) | error |", "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['mu']:g} | {r['motor_tension_n']:.2f} | {r['wrap_deg']:.2f}° | {r['anchor_over_motor']:.4f} | "
                     f"{r['capstan_exp_minus_mu_theta']:.4g} | {r['error_percent']:+.2f} % |".replace("+-", "−").replace("| -", "| −"))
    return "\n".join(lines)


def plot(loops: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from continuum_sim.configio import atomic_write_figure

    fig, ax = plt.subplots(figsize=(6.0, 4.2))
    for mu, (T, bend) in loops.items():
        n = len(T) // 2
        style = {"color": "0.5", "ls": "--"} if mu == 0 else {"color": "C3"}
        ax.plot(bend[: n + 1], T[: n + 1], marker="^", ms=4, label=f"μ = {mu:g}, loading", **style)
        if mu != 0:
            ax.plot(bend[n:], T[n:], marker="v", ms=4, color="C0", label=f"μ = {mu:g}, unloading")
    ax.set_xlabel("proximal section bend (deg)")
    ax.set_ylabel("motor tension on cable_0_0 (N)")
    ax.set_title("Cable friction: section bend vs motor tension (static levels)")
    ax.grid(alpha=0.3)
    ax.legend()
    atomic_write_figure(fig, path)


def scenario_runs(repeats: int) -> list[dict]:
    """The whole default task, μ = 0 vs the default μ: closed (``repeats`` times, interleaved; once at μ = 0.2) and open loop."""
    from continuum_sim.scenario.config import merged
    from continuum_sim.scenario.runner import run_scenario

    rows = []
    mus = (0.0, DEFAULT_MU)
    plan = [("closed", mu) for _ in range(repeats) for mu in mus] + [("closed", 0.2)] + [("open", mu) for mu in mus]
    from continuum_sim.plant import passive

    passive.compile_callback()  # compile/load before timing
    for mode, mu in plan:
        config = merged(ScenarioConfig.default(), {"model": {"cable_friction": {"mu": mu}}, "control": {"mode": mode}})
        t0 = time.process_time()
        m = run_scenario(config, None)
        cpu = time.process_time() - t0
        rows.append(
            {
                "mode": mode,
                "mu": mu,
                "cpu_s": round(cpu, 2),
                "cutting_error_mm": {k: round(v, 3) for k, v in m["cutting_tip_error_mm"].items()},
                "cut_path_deviation_mean_mm": round(m["cut_path_deviation_mm"]["mean"], 3),
                "tip_error_all_mean_mm": {arm: round(e["all"]["mean"], 3) for arm, e in m["tip_error_mm"].items()},
                "sample_detached": m["sample_detached"],
                "sample_held_at_end": m["sample_held_at_end"],
                "spindle_stall_events": m.get("cutting", {}).get("stall_events"),
                "anchor_ratio_min_max": [round(m["cable_friction"][k], 3) for k in ("anchor_ratio_min", "anchor_ratio_max")],
                "tension_change_mean_abs_percent": round(m["cable_friction"]["tension_change_mean_abs_percent"], 2),
            }
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--levels", type=int, default=8)
    parser.add_argument("--hold", type=int, default=2000, help="most steps a tension level is held to rest (4 ms each)")
    parser.add_argument("--plot", type=Path, default=None)
    parser.add_argument("--skip", nargs="*", default=[], choices=["step", "compile", "capstan", "hysteresis", "scenario"])
    parser.add_argument("--scenario-repeats", type=int, default=2, help="closed-loop whole-task runs per μ (CPU time)")
    parser.add_argument("--json", type=Path, default=None, help="also write the JSON here")
    parser.add_argument("--md", type=Path, default=None, help="write the capstan table (Markdown) here")
    args = parser.parse_args(argv)
    out: dict = {"default_mu": DEFAULT_MU, "presliding_m": DEFAULT_PRESLIDING, "load_average": os.getloadavg()}
    if "compile" not in args.skip:
        out["compile"] = compile_cost()
    if "step" not in args.skip:
        out["step"] = step_cost(args.steps, args.repeats)
    if "capstan" not in args.skip:
        out["capstan"] = capstan()
    if "hysteresis" not in args.skip:
        loops = hysteresis(args.levels, args.hold)
        out["hysteresis"] = {
            str(mu): {"tension_n": [round(t, 2) for t in T], "bend_deg": [round(b, 2) for b in bend]} for mu, (T, bend) in loops.items()
        }
        out["hysteresis"]["summary"] = hysteresis_summary(loops, args.levels)
        if args.plot is not None:
            plot(loops, args.plot)
    if "scenario" not in args.skip:
        out["scenario"] = scenario_runs(args.scenario_repeats)
    text = json.dumps(out, indent=2)
    print(text)
    for path, body in ((args.json, text), (args.md, capstan_table(out["capstan"]) if "capstan" in out else None)):
        if path is not None and body is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
