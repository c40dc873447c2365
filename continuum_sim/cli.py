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

    from .report import write_kinematics_report

    geometry = _load_geometry(args.config)
    out = Path(args.out)
    write_kinematics_report(geometry, out)
    print(f"wrote kinematics report to {out}/ (the sample-removal scenario is not built yet)")
    if args.video:
        print("--video: no scenario video yet; it arrives with the scenario")
    return 0


def _cmd_build_model(args: argparse.Namespace) -> int:
    from .model.export import export_models

    if args.config is None:
        paths = export_models(args.out)
    else:
        from .scenario.config import ScenarioConfig

        config = ScenarioConfig.from_toml(args.config)
        paths = export_models(args.out, config.arm, config.layout, config.model)
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="continuum-sim", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    fk = sub.add_parser("fk", help="tip pose and cable lengths of one configuration")
    fk.add_argument("q", nargs=6, type=float, metavar="Q", help="θ0 φ0 θ1 φ1 θ2 φ2 (radians unless --deg)")
    fk.add_argument("--deg", action="store_true", help="angles are in degrees")
    fk.add_argument("--config", help="arm geometry TOML file")
    fk.add_argument("--json", action="store_true", help="print JSON")
    fk.set_defaults(func=_cmd_fk)

    run = sub.add_parser("run", help="the main job: run the sample-removal scenario, write a run folder")
    run.add_argument("--config", help="configuration TOML file")
    run.add_argument("--out", default="runs/default", help="run folder (default: runs/default)")
    run.add_argument("--video", action="store_true", help="render an MP4 off-screen")
    run.set_defaults(func=_cmd_run)

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
