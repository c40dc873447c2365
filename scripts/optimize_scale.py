"""docs/optimize.md, throughput and scale: the measured table and the estimate for larger clusters, from benchmarks/optimize.json.

    python scripts/optimize_scale.py measured [FILE]                  # local 1 / 2 workers, the loopback cluster
    python scripts/optimize_scale.py estimate [FILE] [--cores 32]     # designs per hour on 10 and 100 nodes

Each prints one Markdown table (no blank line) that a ``check-block`` marker compares with the
page (``scripts/check_docs.py``). FILE defaults to benchmarks/optimize.json (stage
``optimize-throughput``).

The estimate is the study's generation loop with the measured costs: a generation of B designs
x S samples runs on P = nodes x cores workers in ceil(B x S / P) waves of one evaluation each
(c s, the measured worker CPU per evaluation: a dedicated core per worker), after the driver
has told the previous generation and asked this one, serially, d s per design (the measured
ask + tell CPU at the largest told history). B = min(1024, P / S): the spec allows at most
1024 designs per generation. Designs per hour = 3600 x B / (B x d + waves x c).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = ROOT / "benchmarks" / "optimize.json"
MAX_BATCH = 1024  # optimizer.batch's upper bound (continuum_sim/optimize/spec.py)
LABELS = {"local_1": "local, 1 worker", "local_2": "local, 2 workers", "ray_2x1": "Ray, 2 nodes x 1 CPU (loopback, token)"}


def _load(path: str | None) -> dict:
    return json.loads(Path(path or DEFAULT).read_text())


def _fmt_s(value: float | None) -> str:
    return "–" if value is None else f"{value:.1f}"


def measured(data: dict) -> list[str]:
    rows = [
        "| set-up | designs | evaluations / h | wall (s) | worker CPU / evaluation (s) | driver CPU (s) "
        "| worker start-up (s) | cores the study got | load (1 min) before |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, s in data["setups"].items():
        rows.append(f"| {LABELS.get(name, name)} | {s['evaluations']} | {s['evaluations_per_hour']:.0f} | {s['wall_s']:.1f} "
                    f"| {s['worker_cpu_s_per_evaluation']:.2f} | {s['driver_cpu_s']:.2f} | {_fmt_s(s['worker_startup_s'])} "
                    f"| {s['cores_used']:.2f} | {s['loadavg_1min_before']:.1f} |")
    return rows


def inputs(data: dict) -> tuple[float, float]:
    """(c, d): worker CPU per evaluation on the cluster, the driver's ask + tell per design at the largest told history."""
    c = data["setups"]["ray_2x1"]["worker_cpu_s_per_evaluation"]
    last = data["driver"]["generations"][-1]
    return c, (last["ask_ms_per_trial"] + last["tell_ms_per_trial"]) / 1000.0


def estimate(data: dict, cores: int) -> list[str]:
    c, d = inputs(data)
    rows = [
        "| nodes x cores | samples S | batch B | waves | driver B x d (s) | evaluations waves x c (s) | designs / h "
        "| all cores busy (P x 3600 / (S x c)) | busy cores | limited by |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for nodes, samples in ((10, 1), (100, 1), (100, 8)):
        p = nodes * cores
        batch = min(MAX_BATCH, p // samples)
        waves = math.ceil(batch * samples / p)
        t_driver, t_eval = batch * d, waves * c
        per_hour = 3600.0 * batch / (t_driver + t_eval)
        ideal = p * 3600.0 / (samples * c)
        busy = min(p, batch * samples) * t_eval / (t_driver + t_eval)
        limits = []
        if batch * samples < p:
            limits.append(f"batch cap {MAX_BATCH}")
        if t_driver > 0.25 * t_eval:
            limits.append("driver's ask/tell")
        rows.append(f"| {nodes} x {cores} | {samples} | {batch} | {waves} | {t_driver:.1f} | {t_eval:.1f} | {per_hour:,.0f} "
                    f"| {ideal:,.0f} | {busy:,.0f} of {p} | {', '.join(limits) or 'the evaluations'} |")
    return rows


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=("measured", "estimate"))
    parser.add_argument("file", nargs="?")
    parser.add_argument("--cores", type=int, default=32, help="cores per node (estimate)")
    args = parser.parse_args(argv)
    data = _load(args.file)
    print("\n".join(measured(data) if args.what == "measured" else estimate(data, args.cores)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
