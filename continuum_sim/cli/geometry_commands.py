"""The kinematics and planning commands: ``fk``, ``ik``, ``plan``, ``workspace`` (no MuJoCo, no GL)."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from ..configio import ConfigError
from ..geometry import ArmGeometry
from .errors import UsageError, clip_line

MAX_TARGET_M = 100.0  # |coordinate| of an ik target: the arm reaches 0.54 m; beyond this only overflow lies


def _load_geometry(path: str | None) -> ArmGeometry:
    """An arm geometry TOML, or a scenario TOML (the arm of its ``[arm]`` table, as `run` builds it)."""
    if path is None:
        return ArmGeometry.default()
    from ..configio import config_from_file, from_dict

    def build(data: dict) -> ArmGeometry:
        if "arm" in data and "sections" not in data:
            from ..scenario.config import ScenarioConfig

            return from_dict(ScenarioConfig, data).arm
        return from_dict(ArmGeometry, data)

    return config_from_file(path, build)


def _cmd_fk(args: argparse.Namespace) -> int:
    from .. import kinematics as kin

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


def _load_layout(path: str | None):
    from ..configio import config_from_file, from_dict
    from ..layout import TaskLayout

    return TaskLayout() if path is None else config_from_file(path, lambda data: from_dict(TaskLayout, data))


def _load_plan_config(path: str | None):
    from ..configio import config_from_file, from_dict
    from ..toolpath import PlanConfig

    return PlanConfig() if path is None else config_from_file(path, lambda data: from_dict(PlanConfig, data))


def _target_from_args(args: argparse.Namespace) -> np.ndarray:
    from .. import kinematics as kin

    if args.matrix is not None:
        try:
            T = np.array(json.loads(args.matrix), dtype=float)
        except (ValueError, TypeError, RecursionError) as exc:
            raise UsageError(f"--matrix: must be a JSON 4x4 list of numbers ({clip_line(str(exc), 80)})") from None
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
    from ..ik import IKOptions, solve_ik

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
    from ..configio import atomic_write_text, check_output_dir, save_toml
    from ..plotting_ik import plot_plan_overview, plot_plan_timeseries, plot_shape_parameters
    from ..toolpath import arm_clearance, plan_task, save_plan, solve_planar_demo

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
    from ..configio import atomic_write_text, check_output_dir
    from ..toolpath import grinder_poses, gripper_poses
    from ..workspace import WorkspaceConfig, check_poses, compute_workspace, plot_workspace

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
