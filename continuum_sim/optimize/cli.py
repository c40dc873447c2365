"""``continuum-sim optimize SPEC.toml``: search the design space for the best (robust) designs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def cmd_optimize(args: argparse.Namespace) -> int:
    from ..configio import check_output_dir
    from .spec import load_spec
    from .study import run_study

    spec = load_spec(args.spec)
    out = Path(args.out) if args.out else Path("runs/optimize") / Path(args.spec).stem
    check_output_dir(out, create=False)
    try:
        result = run_study(spec, out, workers=args.workers, backend=args.backend, address=args.address, progress=not args.quiet,
                           spec_path=args.spec)
    except KeyboardInterrupt:
        print(f"continuum-sim optimize: interrupted; told trials and finished evaluations are kept in {out}, rerun to resume",
              file=sys.stderr)
        return 130
    summary = result.summary
    print(f"{result.root}: {spec.optimizer.sampler}, {result.n_trials} designs ({summary['states']['FAIL']} failed, "
          f"{summary['feasible']} feasible); this run: {result.n_evaluated} evaluations, {result.n_reused} reused, "
          f"{result.n_resumed} interrupted designs re-run; CPU {summary['cpu_s']:.0f} s in all")
    if not args.quiet:
        for best in summary["best"][:10]:
            values = ", ".join(f"{k} {v:.4g}" for k, v in best["values"].items())
            params = ", ".join(f"{k} = {v:.4g}" for k, v in best["params"].items())
            print(f"  trial {best['trial']}: {values} | {params} -> {best['config']}")
        print("  report: summary.json, trials.csv, pareto.csv, plots/, best/*.toml (continuum-sim run --config)")
    return 0


def add_optimize_parser(sub: Any) -> None:
    """Register ``optimize`` on the CLI's subparsers."""
    p = sub.add_parser("optimize", help="design optimisation (Optuna: NSGA-II, TPE, CMA-ES), robust to assumed parameters; resumable")
    p.add_argument("spec", metavar="SPEC.toml", help="study spec: variables, objectives, constraints, robustness (docs/optimize.md)")
    p.add_argument("--out", help="study folder (default: runs/optimize/<spec name>); rerun to resume")
    p.add_argument("--workers", type=int, help="parallel workers (default: all cores; Ray: cluster CPUs)")
    p.add_argument("--backend", choices=("local", "ray"), default="local", help="where evaluations run (default: local)")
    p.add_argument("--address", help="Ray cluster address (--backend ray; default: start a local one)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or best designs")
    p.set_defaults(func=cmd_optimize)
