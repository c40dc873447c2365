"""The argument parser of ``continuum-sim``: every subcommand, its options and its handler."""

from __future__ import annotations

import argparse

from .errors import OneLineParser
from .geometry_commands import _cmd_fk, _cmd_ik, _cmd_plan, _cmd_workspace
from .run_commands import _cmd_build_model, _cmd_metrics, _cmd_run, _cmd_sweep, _cmd_view

DESCRIPTION = (
    "Simulate the dual-arm, cable-driven continuum robot of 'Collaborative Continuum Robots for Remote "
    "Engineering Operations' (Biomimetics 2023) in MuJoCo: plan and run its sample-removal task, check the "
    "model against independent references, and study designs and the assumed parameters."
)
EPILOG = (
    "Start with 'continuum-sim run --out runs/default' (the whole task; add --video for an MP4). "
    "'continuum-sim COMMAND --help' lists a command's options. Bad input ends with one line on stderr and "
    "exit code 2 (docs/errors.md); the documentation is README.md and docs/."
)


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="continuum-sim", description=DESCRIPTION, epilog=EPILOG)
    parser.add_argument("--debug", action="store_true", help="show tracebacks (also accepted after the command)")
    sub = parser.add_subparsers(dest="command", required=True, title="commands", metavar="COMMAND")

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

    from ..validation.report import add_validate_parser  # `validate`: every reference check, one report

    add_validate_parser(sub)

    from .params import add_params_parser  # `params`: the parameter registry (docs/parameters.md)

    add_params_parser(sub)

    from ..sensitivity.cli import add_sensitivity_parser  # `sensitivity`: Morris/Sobol' studies (docs/sensitivity.md)

    add_sensitivity_parser(sub)

    from ..optimize.cli import add_evaluate_parser, add_optimize_parser  # `optimize`, `evaluate`: design optimisation (docs/optimize.md)

    add_optimize_parser(sub)
    add_evaluate_parser(sub)

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

    from ..sysid.cli import add_commands as add_sysid_commands  # replay, synthesize, identify (docs/sysid.md)

    add_sysid_commands(sub)
    from ..report.cli import add_commands as add_report_commands  # report, export (docs/report.md)

    add_report_commands(sub)
    return parser


# ------------------------------------------------------------------ error boundary
# Exit codes (docs/errors.md). Every expected failure ends with ONE line on stderr.
