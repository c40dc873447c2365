"""``continuum-sim`` command line. Bad input → one line on stderr and exit code 2 (docs/errors.md)."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from typing import NoReturn

import numpy as np

from .configio import ConfigError
from .geometry import ArmGeometry


class UsageError(Exception):
    """A command-line value is invalid (message names the option)."""


MAX_TARGET_M = 100.0  # |coordinate| of an ik target: the arm reaches 0.54 m; beyond this only overflow lies


def _load_geometry(path: str | None) -> ArmGeometry:
    """An arm geometry TOML, or a scenario TOML (the arm of its ``[arm]`` table, as `run` builds it)."""
    if path is None:
        return ArmGeometry.default()
    from .configio import config_from_file, from_dict

    def build(data: dict) -> ArmGeometry:
        if "arm" in data and "sections" not in data:
            from .scenario.config import ScenarioConfig

            return from_dict(ScenarioConfig, data).arm
        return from_dict(ArmGeometry, data)

    return config_from_file(path, build)


def _cmd_fk(args: argparse.Namespace) -> int:
    from . import kinematics as kin

    geometry = _load_geometry(args.config)
    q = np.array(args.q, dtype=float)
    if not np.all(np.isfinite(q)):
        raise UsageError("q: all values must be finite numbers")
    if args.deg:
        q = np.radians(q)
    if q.shape != (2 * geometry.n_sections,):
        where = "the default arm" if args.config is None else f"the arm of {args.config}"
        raise UsageError(f"Q: expected {2 * geometry.n_sections} values (θ, φ for each of the {geometry.n_sections} "
                         f"sections of {where}), got {q.size}")
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
    from .configio import check_output_dir
    from .limits import check_cameras, check_scenario
    from .runfolder import discard_if_empty, finish, mark_running, prepare_run_folder
    from .scenario.config import ScenarioConfig, merged

    config = ScenarioConfig.default() if args.config is None else ScenarioConfig.from_toml(args.config)
    if args.control is not None:
        config = merged(config, {"control": {"mode": args.control}})
    if args.controller in ("open", "closed"):
        config = merged(config, {"control": {"mode": args.controller, "controller": ""}})
    elif args.controller is not None:
        config = merged(config, {"control": {"controller": args.controller}})
    if args.no_overlay:
        config = merged(config, {"simulation": {"video_overlay": False}})
    # Everything that can be refused is refused before the folder is touched.
    from .controllers import controller_spec, load_controller

    controller = load_controller(controller_spec(config))  # a broken controller: one line, exit 2
    out = check_output_dir(args.out, create=False)
    check_scenario(config)
    if args.video:
        check_cameras(config)
    prepare_run_folder(out, overwrite=args.overwrite)
    out = check_output_dir(args.out)
    mark_running(out)
    from .scenario.runner import SimulationDiverged, run_scenario

    try:
        metrics = run_scenario(config, out, video=args.video, progress=not args.quiet, controller=controller)
    except SimulationDiverged as exc:
        finish(out, "diverged", str(exc))
        _write_run_report(out)
        print("outcome: task FAILED: diverged (metrics.json: status_reason)")
        print(f"continuum-sim run: error: {exc}", file=sys.stderr)
        return EXIT_DIVERGED
    except BaseException as exc:  # Ctrl-C, SIGTERM, disk full, a refused plan, a bug: the folder says so
        if isinstance(exc, (ConfigError, UsageError)) and discard_if_empty(out):
            raise  # refused before anything was written (e.g. an unreachable plan): no run folder is left
        interrupted = isinstance(exc, (KeyboardInterrupt, _Terminated))
        finish(out, "interrupted" if interrupted else "failed",
               _clip(f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__, 200))
        raise
    finish(out, "complete")
    rounded = _rounded
    summary = {
        "task_completed": metrics["task"]["completed"],
        "task_failure": metrics["task"]["failure"],
        "sample_detached": metrics["sample_detached"],
        "sample_held_at_end": metrics["sample_held_at_end"],
        "detached_before_cut_complete": metrics["detached_before_cut_complete"],
        "cutting_tip_error_mm_mean": rounded(metrics["cutting_tip_error_mm"]["mean"], 4),
        "spindle_axis_error_deg_max": rounded(metrics["spindle_axis_error_deg"]["max"], 4),
        "min_arm_distance_mm": round(1000 * metrics["min_arm_distance_m"], 2),
        "control": metrics["control"],
        "cpu_real_time_factor": rounded(metrics["cpu_real_time_factor"], 2),
        "wall_real_time_factor": rounded(metrics["wall_real_time_factor"], 2),
    }
    print(json.dumps(summary, indent=2))
    _write_run_report(out)
    print(f"run folder: {out}/ (report.html, metrics.json, trajectory.npz, plots/, model/{', video.mp4' if args.video else ''})")
    completed, failure = metrics["task"]["completed"], metrics["task"]["failure"]
    print("outcome: task completed" if completed else f"outcome: task FAILED: {failure} (metrics.json: task.failure)")
    if args.require_completed and not completed:
        print(f"continuum-sim run: the task failed: {failure} (--require-completed)", file=sys.stderr)
        return EXIT_NEGATIVE
    return 0


def _rounded(value: float | None, digits: int) -> float | None:
    """``round`` that keeps None (a figure the run has not got, e.g. no cutting in a partial run)."""
    return None if value is None else round(value, digits)


def _write_run_report(out) -> None:
    """report.html of the run folder (continuum_sim.report: reads the folder's files, no GL)."""
    from .report import write_report

    write_report(out, "run")


def _cmd_metrics(args: argparse.Namespace) -> int:
    from pathlib import Path

    run_dir = Path(args.run_dir)
    for name in ("config.toml", "trajectory.npz"):
        if not (run_dir / name).is_file():
            raise UsageError(f"RUN_DIR: {run_dir} has no {name} (not a run folder, or the run did not finish)")
    from .configio import atomic_write_text
    from .scenario.runner import metrics_text, recompute_metrics
    from .scenario.trajectory import Trajectory

    try:  # a damaged or foreign file is bad input, not a bug
        Trajectory.load(run_dir / "trajectory.npz")
    except Exception as exc:  # noqa: BLE001 - zip, pickle, missing keys, truncation: all mean unreadable
        raise UsageError(f"RUN_DIR: {run_dir}/trajectory.npz is not a readable trajectory ({type(exc).__name__}: {exc})") from None
    text = metrics_text(recompute_metrics(run_dir))
    written = run_dir / "metrics.json"
    if args.write:
        atomic_write_text(written, text)
        print(f"wrote {written}")
        return 0
    print(text)
    if written.exists() and written.read_text() != text:
        print(f"continuum-sim metrics: {written} differs from the recomputed metrics", file=sys.stderr)
        return EXIT_NEGATIVE
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
    from .configio import check_output_dir
    from .model.export import export_models

    check_output_dir(args.out, create=False)
    from .limits import check_model_geometry
    from .scenario.config import ScenarioConfig

    # No --config: the shipped scenario defaults, i.e. the model `continuum-sim run` simulates.
    config = ScenarioConfig.default() if args.config is None else ScenarioConfig.from_toml(args.config)
    check_model_geometry(config)
    check_output_dir(args.out)
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

    from .configio import check_output_dir
    from .sweep import load_spec, run_sweep
    from .sweep.report import format_table

    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers: must be >= 1 (got {args.workers})")
    out = check_output_dir(args.out if args.out is not None else Path("sweeps") / Path(args.spec).stem, create=False)
    spec = load_spec(args.spec, progress=not args.quiet)  # every check happens here, before any work
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
    from .report import write_report

    write_report(result.root, "sweep")  # report.html: the comparison table and the plots on one page
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
        except (ValueError, TypeError, RecursionError) as exc:
            raise UsageError(f"--matrix: must be a JSON 4x4 list of numbers ({_clip(str(exc), 80)})") from None
        if T.shape != (4, 4):
            raise UsageError(f"--matrix: must be a 4x4 list of numbers (got shape {T.shape})")
        if not np.all(np.isfinite(T)):
            bad = T[~np.isfinite(T)][0]
            raise UsageError(f"--matrix: entries must be finite numbers (got {'NaN' if np.isnan(bad) else bad})")
        if np.abs(T[:3, 3]).max() > MAX_TARGET_M:
            raise UsageError(f"--matrix: position entries must satisfy |x| <= {MAX_TARGET_M:g} m")
        return T
    if args.position is None:
        raise UsageError("give the target as --position X Y Z [--rotvec RX RY RZ | --zaxis ZX ZY ZZ] or --matrix JSON")
    if max(abs(v) for v in args.position) > MAX_TARGET_M:
        raise UsageError(f"--position: each coordinate must satisfy |x| <= {MAX_TARGET_M:g} m (got {args.position})")
    T = np.eye(4)
    T[:3, 3] = args.position
    if args.rotvec is not None and args.zaxis is not None:
        raise UsageError("--rotvec and --zaxis are exclusive")
    if args.rotvec is not None:
        rv = np.array(args.rotvec, dtype=float)
        if np.abs(rv).max() > 1e4:
            raise UsageError("--rotvec: each component must satisfy |r| <= 10000 (rad, or deg with --deg)")
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
        if len(args.q0) != 2 * geometry.n_sections:
            raise UsageError(f"--q0: expected {2 * geometry.n_sections} values (θ, φ per section), got {len(args.q0)}")
        q0 = np.radians(args.q0) if args.deg else np.array(args.q0, dtype=float)
    for name, value, low, high in (("--k1", args.k1, 0.0, 1e6), ("--k2", args.k2, 0.0, 1e6), ("--tol", args.tol, 0.0, 1.0)):
        if not low < value <= high:
            raise UsageError(f"{name}: must satisfy {low:g} < {name.lstrip('-')} <= {high:g} (got {value!r})")
    options = IKOptions(position_weight=args.k1, orientation_weight=args.k2, position_tolerance=args.tol,
                        orientation_tolerance=args.tol)
    try:
        with np.errstate(all="ignore"):  # overflow inside the solver is reported below, once
            res = solve_ik(geometry, target, args.orientation, args.phase, q0, tool=tool, base=base, options=options)
    except (OverflowError, FloatingPointError) as exc:
        raise UsageError(f"numeric overflow in the solver ({exc}); check the target and --k1/--k2") from None
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
    from .configio import atomic_write_text, check_output_dir, save_toml
    from .plotting_ik import plot_plan_overview, plot_plan_timeseries, plot_shape_parameters
    from .toolpath import arm_clearance, plan_task, save_plan, solve_planar_demo

    geometry = _load_geometry(args.config)
    layout = _load_layout(args.layout)
    cfg = _load_plan_config(args.plan)
    if args.progress:
        import dataclasses

        cfg = dataclasses.replace(cfg, progress=True)
    out = check_output_dir(args.out, create=False)
    plan = plan_task(geometry, layout, cfg)
    check_output_dir(out)
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
    from .configio import atomic_write_text, check_output_dir
    from .toolpath import grinder_poses, gripper_poses
    from .workspace import WorkspaceConfig, check_poses, compute_workspace, plot_workspace

    geometry = _load_geometry(args.config)
    layout = _load_layout(args.layout)
    cfg = _load_plan_config(args.plan)
    out = check_output_dir(args.out, create=False)
    ws_cfg = WorkspaceConfig(samples=args.samples, voxel=args.voxel, point=args.point, seed=args.seed)
    ws = compute_workspace(geometry, layout, ws_cfg, progress=args.progress)
    gp, hp = grinder_poses(layout, cfg), gripper_poses(layout, cfg)
    summary = ws.summary()
    task = {}
    for arm, poses, _mode in (("left", gp, "axis"), ("right", hp, "full")):
        pts = np.array([p[:3, 3] for p in poses.values()])
        inside = ws.arm(arm).contains(pts, dilate=1)
        task[arm] = {name: bool(v) for name, v in zip(poses, inside)}
    summary["task_positions_inside_sampled_workspace"] = task
    # The authority on reachability (position and orientation): IK; raises naming the first failure.
    check_poses(geometry, layout, "left", list(gp.items()), "axis", cfg.grinder_phase, cfg.ik, ws)
    check_poses(geometry, layout, "right", list(hp.items()), "full", cfg.gripper_phase, cfg.ik, ws)
    summary["task_poses_reachable"] = True
    check_output_dir(out)
    points = {"grinder key poses": np.array([p[:3, 3] for p in gp.values()]),
              "gripper key poses": np.array([p[:3, 3] for p in hp.values()])}
    plot_workspace(ws, out / "workspace.png", layout, points, section_y=args.section_y)
    atomic_write_text(out / "workspace.json", json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="continuum-sim", description=__doc__)
    parser.add_argument("--debug", action="store_true", help="show tracebacks (also accepted after the command)")
    sub = parser.add_subparsers(dest="command", required=True)

    fk = sub.add_parser("fk", help="tip pose and cable lengths of one configuration")
    fk.add_argument("q", nargs="+", type=float, metavar="Q",
                    help="θ, φ per section of the --config arm, 2 values per section (the default 3-section arm: "
                         "θ0 φ0 θ1 φ1 θ2 φ2; radians unless --deg)")
    fk.add_argument("--deg", action="store_true", help="angles are in degrees")
    fk.add_argument("--config", help="arm geometry TOML, or a scenario TOML (its [arm]); sets the number of sections")
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
    ik.add_argument("--q0", nargs="+", type=float, metavar="Q", help="warm start θ, φ per section (θ0 φ0 θ1 φ1 θ2 φ2)")
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
    run.add_argument("--video", action="store_true", help="render an MP4 off-screen (EGL); see docs/video.md")
    run.add_argument("--no-overlay", action="store_true",
                     help="no text over the video's frames (sets simulation.video_overlay = false)")
    run.add_argument("--control", choices=["open", "closed"], help="open = the paper's method, closed = ours (default: config)")
    run.add_argument("--controller", metavar="MODULE:CLASS",
                     help="your own controller class (continuum_sim.controllers.Controller protocol; "
                          "sets control.controller), or open/closed")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument("--overwrite", action="store_true", help="replace the run already in --out (cleared first)")
    run.add_argument("--require-completed", action="store_true",
                     help="exit 1 (naming the failure) when the task fails; default: exit 0 whenever the run itself finished")
    run.set_defaults(func=_cmd_run)

    metrics = sub.add_parser("metrics", help="recompute a run folder's metrics.json from its trajectory.npz and config.toml")
    metrics.add_argument("run_dir", metavar="RUN_DIR", help="a run folder written by `continuum-sim run`")
    metrics.add_argument("--write", action="store_true", help="rewrite RUN_DIR/metrics.json instead of printing")
    metrics.set_defaults(func=_cmd_metrics)

    from .validation.report import add_validate_parser  # `validate`: every reference check, one report

    add_validate_parser(sub)

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

    sweep = sub.add_parser("sweep", help="evaluate a grid of design variants; resumable (docs/sweeps.md)")
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
    from .report.cli import add_commands as add_report_commands  # report, export (docs/report.md)

    add_report_commands(sub)
    return parser


# ------------------------------------------------------------------ error boundary
# Exit codes (docs/errors.md). Every expected failure ends with ONE line on stderr.
EXIT_OK = 0
EXIT_NEGATIVE = 1  # the command ran but the answer is no (ik unreachable, no display for view)
EXIT_USAGE = 2  # bad input: argument, configuration, spec, path, environment, unreachable cluster
EXIT_DIVERGED = 3  # the simulation diverged (partial results kept, marked diverged)
EXIT_RESOURCES = 4  # the machine ran out of something while working (disk full, memory)
EXIT_INTERNAL = 70  # a bug: an exception nobody expected (rerun with --debug for the traceback)
EXIT_INTERRUPTED = 130  # Ctrl-C (SIGINT)
EXIT_BROKEN_PIPE = 141  # stdout closed by the reader (`continuum-sim ik ... | head`), silently
EXIT_TERMINATED = 143  # SIGTERM
MAX_LINE = 400  # characters of the one error line


class _Terminated(BaseException):
    """SIGTERM, raised in the main thread so cleanup (finally blocks) runs as for Ctrl-C."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors; subcommand parsers inherit it (argparse uses type(parent))."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {_clip(message)} (see {self.prog} --help)\n")


def _clip(text: str, limit: int = MAX_LINE) -> str:
    """One line, at most ``limit`` characters."""
    line = " ".join(str(text).split())
    return line if len(line) <= limit else f"{line[: limit - 1]}…"


def _check_finite_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Every float option of the chosen command must be finite (argparse's float() accepts nan and inf)."""
    import math

    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))  # noqa: SLF001
    command = sub.choices.get(args.command)
    if command is None:
        return
    for action in command._actions:  # noqa: SLF001
        if action.type is not float:
            continue
        value = getattr(args, action.dest, None)
        name = action.option_strings[0] if action.option_strings else action.metavar or action.dest
        if action.nargs is None and isinstance(value, list):  # argparse turns `--tol=--` into []
            raise UsageError(f"{name}: expected one number")
        values = value if isinstance(value, (list, tuple)) else [value]
        for v in values:
            if isinstance(v, float) and not math.isfinite(v):
                raise UsageError(f"{name}: must be a finite number (got {v!r})")


def _check_environment(args: argparse.Namespace) -> None:
    """Environment variables read later, deep inside an import: check them before any work.

    Only commands that render choose (and check) a GL backend; the others run with GL
    disabled, so a missing or broken GL library never matters to them (docs/errors.md).
    """
    import os

    from .glbackend import VALID_BACKENDS, GLBackendError, disable_gl, require_gl_backend

    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    if requested and requested not in VALID_BACKENDS:
        raise UsageError(f"MUJOCO_GL: must be one of {', '.join(VALID_BACKENDS)} or unset (got {requested[:40]!r})")
    if args.command == "view" or getattr(args, "video", False):
        try:
            require_gl_backend()
        except GLBackendError as exc:
            raise UsageError(str(exc)) from None
    else:
        disable_gl()


def _is_divergence(exc: BaseException) -> bool:
    return any(cls.__name__ == "SimulationDiverged" for cls in type(exc).__mro__)


def _os_error_line(exc: OSError) -> tuple[int, str]:
    import errno

    where = exc.filename if exc.filename is not None else ""
    reason = exc.strerror or str(exc) or type(exc).__name__
    text = f"{where}: {reason}" if where else reason
    if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.ENOMEM):
        return EXIT_RESOURCES, f"could not write results: {text}"
    return EXIT_USAGE, text


def _silence_stdout() -> None:
    """After a broken pipe: point stdout at /dev/null so the interpreter's final flush is quiet."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


class _WarningSummary:
    """Numeric warnings (overflow in ik, ...) as one line at the end instead of a page each."""

    def __init__(self) -> None:
        self.count = 0
        self.first: str | None = None

    def show(self, message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ARG002
        self.count += 1
        if self.first is None:
            self.first = f"{category.__name__}: {message}"

    def line(self, prog: str) -> str | None:
        if not self.count:
            return None
        more = f" ({self.count} warnings in all; --debug shows each)" if self.count > 1 else ""
        return f"{prog}: warning: {_clip(self.first or '', 200)}{more}"


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; returns the exit code (docs/errors.md). ``--debug`` anywhere shows tracebacks."""
    import os
    import signal
    import threading
    import traceback
    import warnings

    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv or os.environ.get("CONTINUUM_SIM_DEBUG", "") not in ("", "0")
    argv = [a for a in argv if a != "--debug"]
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a bad argument (2, one line already printed)
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    prog = f"continuum-sim {args.command}"

    def fail(code: int, message: str) -> int:
        if debug:
            traceback.print_exc()
        try:
            print(f"{prog}: {_clip(message)}", file=sys.stderr)
        except (OSError, ValueError):
            pass
        return code

    def on_sigterm(signum, frame) -> None:  # noqa: ARG001
        raise _Terminated

    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, on_sigterm) if in_main_thread else None
    summary = _WarningSummary()
    old_limit = sys.getrecursionlimit()
    # MuJoCo's model builder (dm_control) recurses once per nested body: 200 segments per
    # section (the documented maximum) nest 600+ bodies; Python 3.11+ frames do not use the C stack.
    sys.setrecursionlimit(max(old_limit, 10_000))
    gl_environment = {name: os.environ.get(name) for name in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}  # restored after
    try:
        with warnings.catch_warnings():
            if not debug:
                warnings.showwarning = summary.show
            _check_environment(args)
            _check_finite_args(parser, args)
            if isinstance(getattr(args, "out", None), str):  # every command's --out, file or folder
                from .configio import check_output_path

                check_output_path(args.out, "--out")
            code = int(args.func(args) or 0)
            sys.stdout.flush()
        note = summary.line(prog)
        if note:
            print(note, file=sys.stderr)
        return code
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        return fail(EXIT_INTERRUPTED, "interrupted (Ctrl-C)")
    except _Terminated:
        return fail(EXIT_TERMINATED, "terminated (SIGTERM)")
    except (ConfigError, UsageError) as exc:
        return fail(EXIT_USAGE, f"error: {exc}")
    except MemoryError:
        return fail(EXIT_RESOURCES, "error: out of memory; reduce the sizes this command was asked for")
    except OSError as exc:
        code, text = _os_error_line(exc)
        return fail(code, f"error: {text}")
    except RecursionError:
        return fail(EXIT_USAGE, "error: input nested too deeply (recursion limit reached)")
    except Exception as exc:  # noqa: BLE001 - the boundary: one line, never a traceback unless --debug
        if _is_divergence(exc):
            return fail(EXIT_DIVERGED, f"error: {exc}")
        return fail(EXIT_INTERNAL, f"internal error: {type(exc).__name__}: {_clip(str(exc), 250)} (rerun with --debug for the traceback)")
    finally:
        sys.setrecursionlimit(old_limit)
        for name, value in gl_environment.items():  # main() called in-process (tests, scripts) leaves it as it was
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        if in_main_thread and previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
