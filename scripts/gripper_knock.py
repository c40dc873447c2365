"""The gripper knock (issue 24), before and after the fix: figure and figures from two run folders.

    continuum-sim run --config docs/calibration/knock_before.toml --out runs/knock_before
    continuum-sim run --out runs/default
    python scripts/gripper_knock.py runs/knock_before runs/default --out docs/calibration

Writes <out>/gripper_knock.png (gripper tool error, gripper contact force and the gripper arm's
cable tensions over the clamping stage, before vs after) and <out>/gripper_knock.json.

"Steady holding tension" of a cable at time t: its median over the plan segment t lies in (one
move or dwell of the plan, e.g. the gripper's joint transfer to the pre-grasp: the tension the
planned shapes need, a knock being a transient on top of it), floored at the configured
pre-tension (slack cables). A cable's spike ratio is tension / holding tension; the check is
ratio <= 2 everywhere outside grasp closure (the plan's "close" segment, jaws closing on the plate).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from continuum_sim.model.options import model_geometry
from continuum_sim.scenario.clearance import gripper_approach_clearance
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.scenario.runner import build_scene_model
from continuum_sim.scenario.trajectory import CONTACT_KINDS, Trajectory
from continuum_sim.toolpath import SEGMENT_NAMES, plan_task


def analyse(run_dir: Path) -> dict:
    config = ScenarioConfig.from_toml(run_dir / "config.toml")
    plan = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    tr = Trajectory.load(run_dir / "trajectory.npz")
    metrics = json.loads((run_dir / "metrics.json").read_text())
    seg = plan.segment[tr.plan_index.astype(int)]
    closing = seg == SEGMENT_NAMES.index("close")
    # contiguous runs of one plan segment (the same segment name recurs in several stages)
    key = tr.stage.astype(int) * 100 + seg
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    bounds = list(zip(starts, np.r_[starts[1:], len(key)]))
    out: dict = {"run": str(run_dir), "cables": {}, "planned_clearance": {}}
    clearance = gripper_approach_clearance(config, plan, build_scene_model(config)[1])
    for name in ("approach", "grasp"):
        d, t, pair = clearance.min_over(SEGMENT_NAMES.index(name))
        out["planned_clearance"][name] = {"min_mm": 1e3 * d, "t_s": t, "pair": list(pair)}
    worst = (0.0, None)
    for arm, a in tr.arms.items():
        T = a.cable_tension
        hold = np.empty_like(T)
        for a0, a1 in bounds:
            hold[a0:a1] = np.median(T[a0:a1], axis=0)
        hold = np.maximum(hold, config.control.pretension)
        ratio = np.where(closing[:, None], 0.0, T / hold)
        for c in range(T.shape[1]):
            k = int(np.argmax(ratio[:, c]))
            out["cables"][f"{arm}/{c}"] = {"peak_ratio": float(ratio[k, c]), "t_s": float(tr.t[k]), "tension_n": float(T[k, c]),
                                          "holding_n": float(hold[k, c])}
            if ratio[k, c] > worst[0]:
                worst = (float(ratio[k, c]), f"{arm}/{c}")
    gripper_arm = tr.tool_arm["gripper"]
    clamp = metrics["tip_error_mm"][gripper_arm]["clamping"]
    out.update({
        "clamping_error_mean_mm": clamp["mean"], "clamping_error_max_mm": clamp["max"],
        "worst_spike_ratio": worst[0], "worst_spike_cable": worst[1],
        "max_cable_tension_n": metrics["max_cable_tension_n"],
        "max_gripper_contact_outside_closure_n": float(tr.contact_force[~closing & (tr.stage == 1), CONTACT_KINDS.index("gripper")].max()),
        "completed": metrics["task"]["completed"], "cutting_error_mean_mm": metrics["cutting_tip_error_mm"]["mean"],
    })
    return out


def figure(runs: dict[str, Path], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex="col", sharey="row")
    for col, (label, run_dir) in enumerate(runs.items()):
        tr = Trajectory.load(run_dir / "trajectory.npz")
        g = tr.arms[tr.tool_arm["gripper"]]
        sel = tr.stage == 1
        t = tr.t[sel]
        axes[0, col].plot(t, 1e3 * np.linalg.norm(g.tcp_pos - g.tcp_plan[:, :3, 3], axis=1)[sel])
        axes[1, col].plot(t, tr.contact_force[sel, CONTACT_KINDS.index("gripper")])
        axes[2, col].plot(t, g.cable_tension[sel])
        axes[0, col].set_title(label)
        axes[2, col].set_xlabel("t (s), clamping stage")
    axes[0, 0].set_ylabel("gripper tool error (mm)")
    axes[1, 0].set_ylabel("gripper contact force (N)")
    axes[2, 0].set_ylabel("gripper-arm cable tensions (N)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--out", type=Path, default=Path("docs/calibration"))
    args = ap.parse_args()
    result = {"before": analyse(args.before), "after": analyse(args.after)}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "gripper_knock.json").write_text(json.dumps(result, indent=1))
    figure({"before (pre-grasp along the tool axis, 35 mm)": args.before, "after (in the plate plane, 50 mm)": args.after},
           args.out / "gripper_knock.png")
    for k in ("before", "after"):
        r = result[k]
        print(f"{k}: clamping error mean/max {r['clamping_error_mean_mm']:.2f}/{r['clamping_error_max_mm']:.2f} mm, "
              f"worst spike {r['worst_spike_ratio']:.2f}x ({r['worst_spike_cable']}), peak tension {r['max_cable_tension_n']:.1f} N, "
              f"gripper contact before closure {r['max_gripper_contact_outside_closure_n']:.2f} N, planned clearance "
              + ", ".join(f"{k} {v['min_mm']:.2f} mm at {v['t_s']:.2f} s ({v['pair'][0]})" for k, v in r["planned_clearance"].items()))


if __name__ == "__main__":
    main()
