"""The ``replay``, ``synthesize`` and ``identify`` subcommands (registered by ``continuum_sim.cli``).

Bad input raises ``ConfigError`` (one line, exit 2 at the CLI's error boundary).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from pathlib import Path
from typing import Any

from ..configio import ConfigError


def _config(path: str | None):
    from ..scenario.config import ScenarioConfig

    return ScenarioConfig.default() if path is None else ScenarioConfig.from_toml(path)


def _out_dir(path: str, option: str = "--out") -> Path:
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise ConfigError(option, f"{path} exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(option, f"cannot create {path} ({exc.strerror or exc})") from None
    return out


def _provenance(out: Path, command: str, config, data: str | None) -> None:
    """``out/provenance.json``: the configuration and the recording (``hashes.spec``: the data file's bytes) hashed."""
    from .. import provenance
    from ..params.registry import registry_sha256

    provenance.record(out, provenance.current_command(command), config_toml=provenance.config_toml(config),
                      registry_sha256=registry_sha256(), spec_path=None if not data else Path(data))


def _recording(args: argparse.Namespace, config):
    from .data import read_recording

    rec = read_recording(args.data, spool_radius=config.arm.spool_radius)
    changes: dict[str, Any] = {}
    for key in ("mode", "tool", "align"):
        if getattr(args, key, None) is not None:
            changes[key] = getattr(args, key)
    if getattr(args, "settle_s", None) is not None:
        changes["settle_s"] = float(args.settle_s)
    if getattr(args, "gravity", None) is not None:
        changes["gravity"] = args.gravity == "on"
    if changes:
        try:
            rec.info = dataclasses.replace(rec.info, **changes)
        except ConfigError as exc:
            raise exc.under("--") from None
    if rec.n_cables != config.arm.n_cables:
        raise ConfigError(args.data, f"has commands for {rec.n_cables} cables, the configured arm has {config.arm.n_cables} "
                                     "(give the robot's configuration with --config)")
    return rec


def _add_recording_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mode", choices=("dynamic", "quasi_static"), help="override the recording's replay mode")
    p.add_argument("--settle-s", type=float, help="override the settling time per command / before the start (s)")
    p.add_argument("--gravity", choices=("on", "off"), help="override the recording's gravity setting")
    p.add_argument("--tool", choices=("auto", "none", "grinder", "gripper"), help="override what rides on the arm")
    p.add_argument("--align", choices=("none", "offset"), help="override the comparison (offset: remove the mean offset)")


def cmd_replay(args: argparse.Namespace) -> int:
    from .replay import run_replay

    config = _config(args.config)
    rec = _recording(args, config)
    out = _out_dir(args.out)
    _provenance(out, "replay", config, args.data)
    metrics = run_replay(config, rec, out)
    summary = {
        "samples": metrics["samples"],
        "position_error_mm": {k: round(v, 4) for k, v in metrics["position_error_mm"].items()},
        **({"orientation_error_deg": {k: round(v, 4) for k, v in metrics["orientation_error_deg"].items()}}
           if "orientation_error_deg" in metrics else {}),
        "align": metrics["align"],
        "mode": metrics["mode"],
        "cpu_s": round(metrics["cpu_s"], 2),
    }
    print(json.dumps(summary, indent=2))
    print(f"replay folder: {out}/ (replay.json, trajectory.npz, config.toml, plots/tool_paths.png)")
    return 1 if metrics["diverged"] else 0


def _parse_set(items: list[str], config):
    from ..configio import get_path, replace_path

    for item in items:
        path, sep, value = item.partition("=")
        path = path.strip()
        if not sep:
            raise ConfigError(f"--set {item}", "must be PATH=VALUE")
        try:
            current = get_path(config, path)
        except ConfigError as exc:
            raise ConfigError(f"--set {path}", f"unknown parameter path ({exc.field}: {exc.message})") from None
        if isinstance(current, bool) or not isinstance(current, (int, float)):
            raise ConfigError(f"--set {path}", f"not a numeric field (it is {type(current).__name__})")
        try:
            number: float | int = int(value) if isinstance(current, int) else float(value)
        except ValueError:
            raise ConfigError(f"--set {path}", f"not a number: {value!r}") from None
        if isinstance(number, float) and not math.isfinite(number):
            raise ConfigError(f"--set {path}", f"must be finite (got {value!r})")
        try:
            config = replace_path(config, path, number)
        except ConfigError as exc:
            raise ConfigError(f"--set {path}", f"out of range ({exc.field}: {exc.message})") from None
    return config


def cmd_synthesize(args: argparse.Namespace) -> int:
    from .data import write_recording
    from .excitation import synthesize

    config = _parse_set(args.set or [], _config(args.config))
    out = Path(args.out)
    if out.exists() and out.is_dir():
        raise ConfigError("--out", f"{args.out} is a folder; give a file name (DATA.csv)")
    rec = synthesize(config, args.arm, args.duration, args.rate, args.noise_mm, args.noise_deg, args.seed,
                     args.amplitude, args.mode, args.settle_s, args.gravity == "on")
    comments = ("synthesised by continuum-sim synthesize with hidden values: " + (", ".join(args.set) if args.set else "defaults"),
                f"noise: {args.noise_mm:g} mm per axis, {args.noise_deg:g} deg per axis; seed {args.seed}")
    write_recording(rec, out, comments)
    print(f"wrote {out}: {len(rec.time)} samples over {rec.time[-1]:g} s, {args.arm} arm, mode {args.mode}")
    return 0


def cmd_identify(args: argparse.Namespace) -> int:
    import sys

    from .identify import identify, parse_fit, write_identify_folder

    config = _config(args.config)
    rec = _recording(args, config)
    if not args.fit:
        raise ConfigError("--fit", "name at least one parameter path, e.g. --fit model.stiffness_scale")
    for name, low in (("--workers", 1), ("--stride", 1), ("--max-nfev", 1), ("--starts", 1)):
        value = getattr(args, name[2:].replace("-", "_"))
        if value < low:
            raise ConfigError(name, f"must be >= {low} (got {value})")
    if not (math.isfinite(args.orientation_weight) and args.orientation_weight >= 0):
        raise ConfigError("--orientation-weight", f"must be a number >= 0 (got {args.orientation_weight})")
    calibration = None
    if args.calibrate_angles is not None:
        from .calibrate import calibrate_angles
        from .data import read_recording

        pulls = rec if args.calibrate_angles == "" else read_recording(args.calibrate_angles)
        config, calibration = calibrate_angles(config, pulls, args.calibrate_angles or args.data)
    params = [parse_fit(spec, config) for spec in args.fit]
    paths = [p.path for p in params]
    if len(set(paths)) != len(paths):
        raise ConfigError("--fit", "a path is given twice")
    out = _out_dir(args.out)
    _provenance(out, "identify", config, args.data)  # at the start: a killed fit's folder says what it was
    result = identify(config, rec, params, nthread=args.workers, orientation_weight=args.orientation_weight,
                      max_nfev=args.max_nfev, progress=not args.quiet, stride=args.stride, starts=args.starts,
                      seed=args.seed)
    if calibration is not None:
        result.report["calibration"] = calibration
        result.report["calibrated_paths"] = [f"arm.sections.{k}.{f}" for k in range(config.arm.n_sections)
                                             for f in ("cable_angles_deg", "cable_angle_offset_deg")]
    r = result.report
    r["strict"] = bool(args.strict)
    write_identify_folder(out, result, rec, args.config)
    _provenance(out, "identify", config, args.data)
    print(json.dumps({
        "parameters": r["parameters"],
        "ci95": {p: d["ci95"] for p, d in r["details"].items()},
        "rmse_before_mm": round(r["rmse_before_mm"], 4),
        "rmse_after_mm": round(r["rmse_after_mm"], 4),
        "unidentifiable": r["unidentifiable"],
        "replays": r["replays"],
        "cpu_s": round(r["cpu_s"], 1),
    }, indent=2))
    for w in r["warnings"]:
        print(f"identify: warning: {w}", file=sys.stderr)
    print(f"identify folder: {out}/ (identified.toml: use with --config; report.json; plots/)")
    if args.strict and r["warnings"]:
        print(f"identify: --strict: {len(r['warnings'])} warning(s), exit 1", file=sys.stderr)
        return 1
    return 0


def add_commands(sub: Any) -> None:
    """Register the three subcommands on the main parser's subparsers."""
    rp = sub.add_parser("replay", help="drive the model with a recording; predicted vs measured tool poses (docs/sysid.md)")
    rp.add_argument("data", metavar="DATA.csv", help="recorded data (docs/sysid.md: format)")
    rp.add_argument("--config", help="scenario TOML (the robot; e.g. an identified.toml)")
    rp.add_argument("--out", default="runs/replay", help="replay folder (default: runs/replay)")
    _add_recording_options(rp)
    rp.set_defaults(func=cmd_replay)

    sy = sub.add_parser("synthesize", help="a recording made by the model along the excitation motion, with noise")
    sy.add_argument("--set", action="append", metavar="PATH=VALUE", help="hidden 'true' parameter value (repeatable)")
    sy.add_argument("--config", help="scenario TOML the --set values apply to")
    sy.add_argument("--arm", choices=("left", "right"), default="left")
    sy.add_argument("--noise-mm", type=float, default=0.2, help="position noise σ per axis, mm (default 0.2)")
    sy.add_argument("--noise-deg", type=float, default=0.2, help="orientation noise σ per axis, deg (default 0.2)")
    sy.add_argument("--seed", type=int, default=0)
    sy.add_argument("--duration", type=float, default=30.0, help="length of the excitation, s (default 30)")
    sy.add_argument("--rate", type=float, default=50.0, help="measurement rate, Hz (default 50)")
    sy.add_argument("--amplitude", type=float, default=0.4, help="key-shape bend as a fraction of max_bend (default 0.4)")
    sy.add_argument("--mode", choices=("dynamic", "quasi_static"), default="dynamic")
    sy.add_argument("--settle-s", type=float, default=0.5, help="settling before the start / per sample (s)")
    sy.add_argument("--gravity", choices=("on", "off"), default="on")
    sy.add_argument("--out", required=True, help="the CSV file to write")
    sy.set_defaults(func=cmd_synthesize)

    idp = sub.add_parser("identify", help="fit config parameters to a recording by simulated replays (least squares)")
    idp.add_argument("data", metavar="DATA.csv")
    idp.add_argument("--fit", action="append", metavar="PATH[=LOW:HIGH]", help="a numeric config path to fit (repeatable)")
    idp.add_argument("--config", help="scenario TOML to start from")
    idp.add_argument("--out", default="runs/identify", help="output folder (default: runs/identify)")
    idp.add_argument("--workers", type=int, default=1, help="threads for the batched replays (default 1)")
    idp.add_argument("--max-nfev", type=int, default=30, help="least-squares iterations at most (default 30)")
    idp.add_argument("--orientation-weight", type=float, default=1.0, help="mm of residual per degree of orientation error")
    idp.add_argument("--stride", type=int, default=1, help="fit on every N-th row (before/after figures use all rows)")
    idp.add_argument("--quiet", action="store_true", help="no progress bar")
    idp.add_argument("--starts", type=int, default=1, help="multi-start: the initial values + N-1 Sobol points (default 1)")
    idp.add_argument("--seed", type=int, default=0, help="seed of the multi-start's scrambled Sobol points")
    idp.add_argument("--strict", action="store_true",
                     help="exit 1 when the fit is not trustworthy (a bound, no movement, the evaluation limit, unidentifiable)")
    idp.add_argument("--calibrate-angles", nargs="?", const="", metavar="PULLS.csv",
                     help="first measure the tendon angles from single-tendon pull rows (of DATA, or of PULLS.csv)")
    _add_recording_options(idp)
    idp.set_defaults(func=cmd_identify)

    from .import_cli import add_import_commands

    add_import_commands(sub)
