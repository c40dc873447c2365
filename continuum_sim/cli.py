"""``continuum-sim`` command line. Bad input → one line on stderr and exit code 2."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

import numpy as np

from .configio import ConfigError
from .geometry import ArmGeometry


class UsageError(Exception):
    """A command-line value is invalid (message names the option)."""


def _load_geometry(path: str | None) -> ArmGeometry:
    return ArmGeometry.default() if path is None else ArmGeometry.from_toml(path)


def _cmd_fk(args: argparse.Namespace) -> int:
    from . import kinematics as kin

    geometry = _load_geometry(args.config)
    q = np.array(args.q, dtype=float)
    if not np.all(np.isfinite(q)):
        raise UsageError("q: all six values must be finite numbers")
    if args.deg:
        q = np.radians(q)
    if q.shape != (2 * geometry.n_sections,):
        raise UsageError(f"q: expected {2 * geometry.n_sections} values (θ, φ per section), got {q.size}")
    for k, section in enumerate(geometry.sections):
        if not 0.0 <= q[2 * k] <= section.max_bend + 1e-12:
            raise UsageError(
                f"q: θ{k} must satisfy 0 <= θ{k} <= {section.max_bend_deg:g} deg (got {np.degrees(q[2 * k]):g} deg)"
            )
    tip = kin.forward_kinematics(geometry, q)
    lengths = kin.cable_lengths(geometry, q)
    delta = lengths - kin.straight_cable_lengths(geometry)
    result = {
        "q_rad": q.tolist(),
        "tip_position_m": tip[:3, 3].tolist(),
        "tip_rotation": tip[:3, :3].tolist(),
        "cable_lengths_m": lengths.tolist(),
        "cable_length_changes_m": delta.tolist(),
        "motor_angles_rad": (delta / geometry.spool_radius).tolist(),
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    np.set_printoptions(precision=6, suppress=True)
    print("tip position [mm]: " + " ".join(f"{1000 * x:.4f}" for x in tip[:3, 3]))
    print("tip rotation:")
    for row in tip[:3, :3]:
        print("  " + " ".join(f"{x:+.6f}" for x in row))
    print("cable                 length [mm]   Δl [mm]   motor [rad]")
    for name, l, d in zip(geometry.cable_names("arm"), lengths, delta):
        print(f"  {name:<18}{1000 * l:12.4f}{1000 * d:10.4f}{d / geometry.spool_radius:12.5f}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .scenario.config import ScenarioConfig, merged

    config = ScenarioConfig.default() if args.config is None else ScenarioConfig.from_toml(args.config)
    if args.control is not None:
        config = merged(config, {"control": {"mode": args.control}})
    out = Path(args.out)
    from .scenario.runner import SimulationDiverged, run_scenario

    try:
        metrics = run_scenario(config, out, video=args.video, progress=not args.quiet)
    except SimulationDiverged as exc:
        print(f"continuum-sim run: error: {exc}", file=sys.stderr)
        return 3
    summary = {
        "sample_detached": metrics["sample_detached"],
        "sample_held_at_end": metrics["sample_held_at_end"],
        "detached_before_cut_complete": metrics["detached_before_cut_complete"],
        "cutting_tip_error_mm_mean": round(metrics["cutting_tip_error_mm"]["mean"], 4),
        "spindle_axis_error_deg_max": round(metrics["spindle_axis_error_deg"]["max"], 4),
        "min_arm_distance_mm": round(1000 * metrics["min_arm_distance_m"], 2),
        "control": metrics["control"],
        "real_time_factor": round(metrics["real_time_factor"], 2),
    }
    print(json.dumps(summary, indent=2))
    print(f"run folder: {out}/ (metrics.json, trajectory.npz, plots/, model/{', video.mp4' if args.video else ''})")
    return 0


def _cmd_view(args: argparse.Namespace) -> int:
    import os

    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        print(
            "continuum-sim view: no display found (DISPLAY and WAYLAND_DISPLAY are unset); "
            "the interactive viewer needs one. Headless: `continuum-sim run --video` renders off-screen.",
            file=sys.stderr,
        )
        return 1
    from .scenario.config import ScenarioConfig
    from .scenario.runner import build_scene_model

    config = ScenarioConfig.default() if args.config is None else ScenarioConfig.from_toml(args.config)
    _, model = build_scene_model(config)
    import mujoco.viewer

    mujoco.viewer.launch(model)
    return 0


def _cmd_build_model(args: argparse.Namespace) -> int:
    from .model.export import export_models

    if args.config is None:
        paths = export_models(args.out)
    else:
        from .scenario.config import ScenarioConfig

        config = ScenarioConfig.from_toml(args.config)
        paths = export_models(args.out, config.arm, config.layout, config.model, config.scene)
    if not args.models_only:
        from pathlib import Path

        from .configio import atomic_write_text
        from .scenario.config import default_scenario_toml

        defaults = Path(__file__).resolve().parent / "data" / "scenario.toml"
        text = default_scenario_toml()
        if not defaults.exists() or defaults.read_text() != text:
            atomic_write_text(defaults, text)
            defaults.chmod(0o644)
        paths.append(defaults)
    for path in paths:
        print(f"wrote {path}")
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .sweep import load_spec, run_sweep
    from .sweep.report import format_table

    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers: must be >= 1 (got {args.workers})")
    spec = load_spec(args.spec)  # every check happens here, before any work
    out = Path(args.out) if args.out else Path("sweeps") / Path(args.spec).stem
    try:
        result = run_sweep(
            spec,
            out,
            workers=args.workers,
            backend=args.backend,
            address=args.address,
            batch=args.batch,
            retry_failed=args.retry_failed,
            progress=not args.quiet,
        )
    except KeyboardInterrupt:
        print(f"continuum-sim sweep: interrupted; finished variants are kept in {out}/records, rerun to resume", file=sys.stderr)
        return 130
    if not args.quiet:
        print(format_table(spec, result.records))
    print(
        f"sweep: {result.n_variants} variants ({result.n_skipped} already recorded, {result.n_run} run, "
        f"{result.n_failed} failed; mode {result.mode}) -> {result.root}/results.csv, {len(result.plots)} plots"
    )
    return 0


def _load_layout(path: str | None):
    from .configio import config_from_file, from_dict
    from .layout import TaskLayout

    return TaskLayout() if path is None else config_from_file(path, lambda data: from_dict(TaskLayout, data))


def _load_plan_config(path: str | None):
    from .configio import config_from_file, from_dict
    from .toolpath import PlanConfig

    return PlanConfig() if path is None else config_from_file(path, lambda data: from_dict(PlanConfig, data))


def _target_from_args(args: argparse.Namespace) -> np.ndarray:
    from . import kinematics as kin

    if args.matrix is not None:
        try:
            T = np.array(json.loads(args.matrix), dtype=float)
        except (ValueError, TypeError) as exc:
            raise UsageError(f"--matrix: must be a JSON 4x4 list of numbers ({exc})") from None
        return T
    if args.position is None:
        raise UsageError("give the target as --position X Y Z [--rotvec RX RY RZ | --zaxis ZX ZY ZZ] or --matrix JSON")
    T = np.eye(4)
    T[:3, 3] = args.position
    if args.rotvec is not None and args.zaxis is not None:
        raise UsageError("--rotvec and --zaxis are exclusive")
    if args.rotvec is not None:
        rv = np.array(args.rotvec, dtype=float)
        T[:3, :3] = kin.exp_so3(np.radians(rv) if args.deg else rv)
    elif args.zaxis is not None:
        z = np.array(args.zaxis, dtype=float)
        n = np.linalg.norm(z)
        if not np.isfinite(n) or n < 1e-12:
            raise UsageError("--zaxis: must be a finite non-zero vector")
        z = z / n
        helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        x = helper - (helper @ z) * z
        x /= np.linalg.norm(x)
        T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return T


def _cmd_ik(args: argparse.Namespace) -> int:
    from .ik import IKOptions, solve_ik

    geometry = _load_geometry(args.config)
    target = _target_from_args(args)
    base = None
    tool: str | float = args.tool
    if args.arm is not None:
        mount = _load_layout(args.layout).mount(args.arm)
        base = mount.base_transform()
        if tool == "auto":
            tool = mount.tool
    if tool == "auto":
        tool = "none"
    if tool not in ("none", "grinder", "gripper"):
        try:
            tool = float(tool)
        except ValueError:
            raise UsageError(f"--tool: must be none, grinder, gripper or a length in metres (got {tool!r})") from None
    q0 = None
    if args.q0 is not None:
        q0 = np.radians(args.q0) if args.deg else np.array(args.q0, dtype=float)
    options = IKOptions(position_weight=args.k1, orientation_weight=args.k2, position_tolerance=args.tol,
                        orientation_tolerance=args.tol)
    try:
        res = solve_ik(geometry, target, args.orientation, args.phase, q0, tool=tool, base=base, options=options)
    except ValueError as exc:
        if isinstance(exc, ConfigError):
            raise
        raise UsageError(str(exc)) from None
    out = {"target": target.tolist(), "frame": "world" if base is not None else "arm base",
           "tool": tool, "orientation": args.orientation, "phase": args.phase, **res.to_dict()}
    print(json.dumps(out, indent=2))
    if not res.success:
        print(f"continuum-sim ik: {res.message}", file=sys.stderr)
        return 1
    return 0


def _cmd_plan(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .configio import atomic_write_text, save_toml
    from .plotting_ik import plot_plan_overview, plot_plan_timeseries, plot_shape_parameters
    from .toolpath import arm_clearance, plan_task, save_plan, solve_planar_demo

    geometry = _load_geometry(args.config)
    layout = _load_layout(args.layout)
    cfg = _load_plan_config(args.plan)
    if args.progress:
        import dataclasses

        cfg = dataclasses.replace(cfg, progress=True)
    plan = plan_task(geometry, layout, cfg)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    save_plan(plan, out / "plan.npz")
    save_toml(layout, out / "layout.toml")
    save_toml(cfg, out / "plan_config.toml")
    report = {"metrics": plan.metrics}
    if not args.no_plots:
        wp = plan.waypoints["left/cutting"]
        plot_shape_parameters(wp["q"], wp["position_error"], wp["orientation_error"],
                              "grinder cutting path, free phase", out / "fig9_grinder_cutting.png")
        demo = solve_planar_demo(geometry, layout, cfg)
        for phase, fig in (("free", "fig9_planar_demo_free.png"), ("planar", "fig11_planar_demo_planar.png")):
            sol = demo[phase]
            plot_shape_parameters(sol.q, sol.position_error, sol.orientation_error,
                                  f"in-plane demo path, {phase} phase", out / fig)
            report[f"planar_demo_{phase}"] = {
                "success": sol.success,
                "points": int(len(sol.q)),
                "position_error_max_m": float(sol.position_error.max()),
                "orientation_error_max_rad": float(sol.orientation_error.max()),
                "max_dtheta_deg": float(np.degrees(np.abs(np.diff(sol.q[:, 0::2], axis=0)).max())),
            }
        plot_plan_overview(plan, geometry, layout, out / "plan_overview.png")
        clearance = arm_clearance(geometry, layout, cfg, plan.q_left, plan.q_right)
        plot_plan_timeseries(plan, clearance, out / "plan_timeseries.png")
    atomic_write_text(out / "plan_report.json", json.dumps(report, indent=2))
    m = plan.metrics
    print(f"plan: {m['duration_s']:.2f} s, {m['samples']} samples at {cfg.sample_rate_hz:g} Hz; "
          f"min arm clearance {1000 * m['min_arm_clearance_m']:.1f} mm ({m['min_arm_clearance_stage']}); "
          f"cut path deviation max {1e6 * m['cut_path_max_deviation_m']:.1f} um; "
          f"IK error max {m['waypoint_position_error_max_m']:.1e} m")
    print(f"wrote {out}/plan.npz, plan_report.json" + ("" if args.no_plots else " and plots"))
    return 0


def _cmd_workspace(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .configio import atomic_write_text
    from .toolpath import gripper_poses, grinder_poses
    from .workspace import WorkspaceConfig, check_poses, compute_workspace, plot_workspace

    geometry = _load_geometry(args.config)
    layout = _load_layout(args.layout)
    cfg = _load_plan_config(args.plan)
    ws_cfg = WorkspaceConfig(samples=args.samples, voxel=args.voxel, point=args.point, seed=args.seed)
    ws = compute_workspace(geometry, layout, ws_cfg, progress=args.progress)
    gp, hp = grinder_poses(layout, cfg), gripper_poses(layout, cfg)
    summary = ws.summary()
    task = {}
    for arm, poses, mode in (("left", gp, "axis"), ("right", hp, "full")):
        pts = np.array([p[:3, 3] for p in poses.values()])
        inside = ws.arm(arm).contains(pts, dilate=1)
        task[arm] = {name: bool(v) for name, v in zip(poses, inside)}
    summary["task_positions_inside_sampled_workspace"] = task
    # The authority on reachability (position and orientation): IK; raises naming the first failure.
    check_poses(geometry, layout, "left", list(gp.items()), "axis", cfg.grinder_phase, cfg.ik, ws)
    check_poses(geometry, layout, "right", list(hp.items()), "full", cfg.gripper_phase, cfg.ik, ws)
    summary["task_poses_reachable"] = True
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    points = {"grinder key poses": np.array([p[:3, 3] for p in gp.values()]),
              "gripper key poses": np.array([p[:3, 3] for p in hp.values()])}
    plot_workspace(ws, out / "workspace.png", layout, points, section_y=args.section_y)
    atomic_write_text(out / "workspace.json", json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="continuum-sim", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    fk = sub.add_parser("fk", help="tip pose and cable lengths of one configuration")
    fk.add_argument("q", nargs=6, type=float, metavar="Q", help="θ0 φ0 θ1 φ1 θ2 φ2 (radians unless --deg)")
    fk.add_argument("--deg", action="store_true", help="angles are in degrees")
    fk.add_argument("--config", help="arm geometry TOML file")
    fk.add_argument("--json", action="store_true", help="print JSON")
    fk.set_defaults(func=_cmd_fk)

    ik = sub.add_parser("ik", help="inverse kinematics of one pose (JSON out; exit 1 if unreachable)")
    ik.add_argument("--position", nargs=3, type=float, metavar=("X", "Y", "Z"), help="target position, metres")
    ik.add_argument("--rotvec", nargs=3, type=float, metavar=("RX", "RY", "RZ"), help="target rotation vector (rad; deg with --deg)")
    ik.add_argument("--zaxis", nargs=3, type=float, metavar=("ZX", "ZY", "ZZ"), help="target tool axis (for --orientation axis)")
    ik.add_argument("--matrix", help="target as a JSON 4x4 homogeneous matrix")
    ik.add_argument("--orientation", choices=["full", "axis"], default="full")
    ik.add_argument("--phase", choices=["free", "planar"], default="free")
    ik.add_argument("--tool", default="auto", help="none, grinder, gripper or a length in m (default: the arm's tool with --arm, else none)")
    ik.add_argument("--arm", choices=["left", "right"], help="target in the world frame of this arm's task mount")
    ik.add_argument("--q0", nargs=6, type=float, metavar="Q", help="warm start θ0 φ0 θ1 φ1 θ2 φ2")
    ik.add_argument("--deg", action="store_true", help="--rotvec and --q0 in degrees")
    ik.add_argument("--k1", type=float, default=10.0, help="position weight, 1/m (paper eq. 8)")
    ik.add_argument("--k2", type=float, default=1.0, help="orientation weight, 1/rad")
    ik.add_argument("--tol", type=float, default=1e-9, help="success tolerance, m and rad")
    ik.add_argument("--config", help="arm geometry TOML file")
    ik.add_argument("--layout", help="task layout TOML file (with --arm)")
    ik.set_defaults(func=_cmd_ik)

    plan = sub.add_parser("plan", help="plan the sample-removal task: timed dual-arm plan, metrics and plots")
    plan.add_argument("--out", default="runs/plan", help="output folder (default: runs/plan)")
    plan.add_argument("--config", help="arm geometry TOML file")
    plan.add_argument("--layout", help="task layout TOML file")
    plan.add_argument("--plan", help="plan configuration TOML file")
    plan.add_argument("--no-plots", action="store_true")
    plan.add_argument("--progress", action="store_true", help="progress bars")
    plan.set_defaults(func=_cmd_plan)

    ws = sub.add_parser("workspace", help="cooperative workspace of both arms; checks the task lies inside")
    ws.add_argument("--out", default="runs/workspace", help="output folder (default: runs/workspace)")
    ws.add_argument("--samples", type=int, default=200_000, help="configurations per arm")
    ws.add_argument("--voxel", type=float, default=0.01, help="voxel edge, m")
    ws.add_argument("--point", choices=["tcp", "tip"], default="tcp")
    ws.add_argument("--seed", type=int, default=0)
    ws.add_argument("--section-y", type=float, default=0.0, help="y of the section view, m")
    ws.add_argument("--progress", action="store_true", help="progress bars")
    ws.add_argument("--config", help="arm geometry TOML file")
    ws.add_argument("--layout", help="task layout TOML file")
    ws.add_argument("--plan", help="plan configuration TOML file")
    ws.set_defaults(func=_cmd_workspace)

    run = sub.add_parser("run", help="the main job: run the sample-removal scenario, write a run folder")
    run.add_argument("--config", help="scenario TOML file (overrides the shipped defaults)")
    run.add_argument("--out", default="runs/default", help="run folder (default: runs/default)")
    run.add_argument("--video", action="store_true", help="render an MP4 off-screen (EGL)")
    run.add_argument("--control", choices=["open", "closed"], help="open = the paper's method, closed = ours (default: config)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=_cmd_run)

    view = sub.add_parser("view", help="open the scene in MuJoCo's interactive viewer (needs a display)")
    view.add_argument("--config", help="scenario TOML file")
    view.set_defaults(func=_cmd_view)

    build = sub.add_parser("build-model", help="regenerate the MJCF models (dual_arm.xml, arm.xml)")
    build.add_argument("--out", default="models", help="output folder (default: models)")
    build.add_argument("--config", help="scenario TOML whose arm/layout/model to build (default: package defaults)")
    build.add_argument(
        "--models-only", action="store_true", help="do not regenerate the shipped scenario defaults (continuum_sim/data/scenario.toml)"
    )
    build.set_defaults(func=_cmd_build_model)

    sweep = sub.add_parser("sweep", help="evaluate a grid of design variants; resumable (README: Parameter sweeps)")
    sweep.add_argument("spec", metavar="SPEC.toml", help="sweep spec: [grid], [evaluation], metrics")
    sweep.add_argument("--out", help="results folder (default: sweeps/<spec name>); rerun to resume")
    sweep.add_argument("--workers", type=int, help="parallel workers (default: all cores; Ray: cluster CPUs)")
    sweep.add_argument("--backend", choices=("local", "ray"), default="local", help="where variants run (default: local)")
    sweep.add_argument("--address", help="Ray cluster address, e.g. 10.0.0.5:6379 (--backend ray; default: start a local one)")
    sweep.add_argument(
        "--batch",
        choices=("auto", "on", "off"),
        default="auto",
        help="share one compiled model between same-structure static variants (auto: when local and static)",
    )
    sweep.add_argument("--retry-failed", action="store_true", help="re-run variants recorded as failed")
    sweep.add_argument("--quiet", action="store_true", help="no progress bar or table")
    sweep.set_defaults(func=_cmd_sweep)

    from .sysid.cli import add_commands as add_sysid_commands  # replay, synthesize, identify (docs/sysid.md)

    add_sysid_commands(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ConfigError, UsageError) as exc:
        print(f"continuum-sim {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
