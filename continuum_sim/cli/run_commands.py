"""The simulation commands: ``run``, ``metrics``, ``view``, ``build-model``, ``sweep``."""

from __future__ import annotations

import argparse
import json
import sys

from ..configio import ConfigError
from .errors import EXIT_DIVERGED, EXIT_NEGATIVE, Terminated, UsageError, clip_line


def _cmd_run(args: argparse.Namespace) -> int:
    from ..configio import check_output_dir
    from ..limits import check_cameras, check_scenario
    from ..runfolder import discard_if_empty, finish, mark_running, prepare_run_folder
    from ..scenario.config import ScenarioConfig, merged

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
    from ..controllers import controller_spec, load_controller

    controller = load_controller(controller_spec(config))  # a broken controller: one line, exit 2
    out = check_output_dir(args.out, create=False)
    check_scenario(config)
    if args.video:
        check_cameras(config)
    prepare_run_folder(out, overwrite=args.overwrite)
    out = check_output_dir(args.out)
    mark_running(out)
    from ..scenario.runner import SimulationDiverged, run_scenario

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
        interrupted = isinstance(exc, (KeyboardInterrupt, Terminated))
        finish(out, "interrupted" if interrupted else "failed",
               clip_line(f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__, 200))
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
    from ..report import write_report

    write_report(out, "run")


def _cmd_metrics(args: argparse.Namespace) -> int:
    from pathlib import Path

    run_dir = Path(args.run_dir)
    for name in ("config.toml", "trajectory.npz"):
        if not (run_dir / name).is_file():
            raise UsageError(f"RUN_DIR: {run_dir} has no {name} (not a run folder, or the run did not finish)")
    from ..configio import atomic_write_text
    from ..scenario.runner import metrics_text, recompute_metrics
    from ..scenario.trajectory import Trajectory

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
    from ..scenario.config import ScenarioConfig
    from ..scenario.runner import build_scene_model

    config = ScenarioConfig.default() if args.config is None else ScenarioConfig.from_toml(args.config)
    _, model = build_scene_model(config)
    import mujoco.viewer

    mujoco.viewer.launch(model)
    return 0


def _cmd_build_model(args: argparse.Namespace) -> int:
    from ..configio import check_output_dir
    from ..model.export import export_models

    check_output_dir(args.out, create=False)
    from ..limits import check_model_geometry
    from ..scenario.config import ScenarioConfig

    # No --config: the shipped scenario defaults, i.e. the model `continuum-sim run` simulates.
    config = ScenarioConfig.default() if args.config is None else ScenarioConfig.from_toml(args.config)
    check_model_geometry(config)
    check_output_dir(args.out)
    paths = export_models(args.out, config.arm, config.layout, config.model, config.scene)
    if not args.models_only:
        from pathlib import Path

        from ..configio import atomic_write_text
        from ..scenario.config import default_scenario_toml

        defaults = Path(__file__).resolve().parent.parent / "data" / "scenario.toml"  # continuum_sim/data/
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

    from ..configio import check_output_dir
    from ..sweep import load_spec, run_sweep
    from ..sweep.report import format_table

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
            spec_path=args.spec,
        )
    except KeyboardInterrupt:
        print(f"continuum-sim sweep: interrupted; finished variants are kept in {out}/records, rerun to resume", file=sys.stderr)
        return 130
    if not args.quiet:
        print(format_table(spec, result.records))
    from ..report import write_report

    write_report(result.root, "sweep")  # report.html: the comparison table and the plots on one page
    print(
        f"sweep: {result.n_variants} variants ({result.n_skipped} already recorded, {result.n_run} run, "
        f"{result.n_failed} failed; mode {result.mode}) -> {result.root}/results.csv, {len(result.plots)} plots"
    )
    return 0
