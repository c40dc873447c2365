"""``continuum-sim sensitivity SPEC.toml``: global sensitivity of the task to the assumed parameters."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def cmd_sensitivity(args: argparse.Namespace) -> int:
    from ..configio import check_output_dir
    from .spec import load_spec
    from .study import run_study

    spec = load_spec(args.spec)
    out = Path(args.out) if args.out else Path("runs/sensitivity") / Path(args.spec).stem
    check_output_dir(out, create=False)
    result = run_study(spec, out, workers=args.workers, backend=args.backend, address=args.address, progress=not args.quiet,
                       spec_path=args.spec)
    summary = result.summary
    print(f"{result.root}: {spec.method}, {result.n_distinct} samples ({result.n_skipped} already recorded, "
          f"{result.n_run} run, {result.n_failed} failed); CPU {summary['cpu_s_total']:.0f} s")
    if not args.quiet and spec.method == "uncertainty":
        a = summary["analysis"]["uncertainty"]
        interval = " – ".join(f"{v:.2f}" for v in a["interval_95"]) if a["interval_95"] else "none"
        print(f"  success ({' and '.join(a['criterion'])}): {a['successes']}/{a['recorded']}, 95 % interval {interval}")
        print(f"  outcomes: {', '.join(f'{why} {n}' for why, n in a['failures'].items()) or 'all succeeded'}; report: summary.md")
    elif not args.quiet:
        key = "mu_star" if spec.method == "morris" else "ST"
        for metric, analysis in summary["analysis"].items():
            indices = analysis.get("indices")
            if not indices:
                print(f"  {metric}: not enough samples")
                continue
            top = sorted(indices.items(), key=lambda kv: -(kv[1][key] or 0.0))[:3]
            print(f"  {metric}: " + ", ".join(f"{p} {key} {v[key]:.3g}" for p, v in top))
        print(f"  strongest overall: {', '.join(summary['strongest'])}; report: summary.json, indices.csv, plots/")
    for note in summary.get("notes", []):
        print(f"  note: {note}")
    for warning in summary.get("warnings", []):  # also in summary.json and summary.md
        print(f"continuum-sim sensitivity: warning: {warning}", file=sys.stderr)
    return 0


def add_sensitivity_parser(sub: Any) -> None:
    """Register ``sensitivity`` on the CLI's subparsers."""
    p = sub.add_parser("sensitivity", help="global sensitivity (Morris, Sobol') of the task to assumed parameters; resumable")
    p.add_argument("spec", metavar="SPEC.toml", help="study spec: parameters, method, evaluation (docs/sensitivity.md)")
    p.add_argument("--out", help="study folder (default: runs/sensitivity/<spec name>); rerun to resume")
    p.add_argument("--workers", type=int, help="parallel workers (default: all cores; Ray: cluster CPUs)")
    p.add_argument("--backend", choices=("local", "ray"), default="local", help="where samples run (default: local)")
    p.add_argument("--address", help="Ray cluster address (--backend ray; default: start a local one)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or ranking")
    p.set_defaults(func=cmd_sensitivity)
