"""Friction replays in parallel (issue 27): identify's Jacobian columns, one process per replay.

Replays N parameter variants of the first ROWS rows of the FTDCR v4 train recording (cable
friction on, μ = 0.15 shipped) through ``sysid.replay.simulate`` with 1 and with 2
workers, and reports wall time, CPU time (this process + its worker processes) and the
load average before and after. The pool is warmed first (fork, one replay per worker), as
``identify`` keeps it for the whole fit. Speed-up = wall(1) / wall(2).

The development machine is shared (2 cores, several sessions): quote the load with the
figures. Run: ``PYTHONPATH=. python benchmarks/sysid_parallel.py [--rows 60] [--variants 4] [--repeat 2]``;
writes ``benchmarks/sysid_parallel.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from continuum_sim.configio import replace_path
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.sysid.data import read_recording
from continuum_sim.sysid.replay import simulate

ROOT = Path(__file__).resolve().parents[1]
FTDCR = ROOT / "validation" / "opencr_ftdcr_v4"


def _proc_cpu(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


def _cpu() -> float:
    """This process's CPU time plus its live pool workers' (they are not waited for, so rusage misses them)."""
    from continuum_sim.sysid import replay

    workers = [pid for pool in replay._POOL.values() for pid in getattr(pool, "_processes", {})]
    return time.process_time() + sum(_proc_cpu(pid) for pid in workers)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", type=int, default=60)
    ap.add_argument("--variants", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    config = ScenarioConfig.from_toml(FTDCR / "recordings" / "robot.toml")
    assert config.model.cable_friction.mu > 0.0
    rec = read_recording(FTDCR / "recordings" / "train.recording.csv")
    rec = rec.subset(np.arange(min(args.rows, len(rec.time))))
    configs = [replace_path(config, "arm.sections.0.stiffness_scale", 1.0 + 0.01 * i) for i in range(args.variants)]
    simulate(configs[:2], rec, nthread=2)  # warm the pool (forks once, as identify does)
    simulate(configs[:1], rec, nthread=1)  # and this process's kernels
    load_before = os.getloadavg()
    out: dict[str, object] = {"rows": len(rec.time), "variants": args.variants, "repeat": args.repeat,
                              "cpu_count": os.cpu_count(), "load_before": load_before}
    results = {}
    for workers in (1, 2, 1, 2)[: 2 * args.repeat]:
        c0, w0 = _cpu(), time.perf_counter()
        preds = simulate(configs, rec, nthread=workers)
        wall, cpu = time.perf_counter() - w0, _cpu() - c0
        assert all(np.all(np.isfinite(p.position)) for p in preds)
        results.setdefault(workers, []).append({"wall_s": wall, "cpu_s": cpu})
        print(f"workers {workers}: wall {wall:.2f} s, cpu {cpu:.2f} s (load {os.getloadavg()[0]:.2f})")
    out["load_after"] = os.getloadavg()
    best = {w: min(r["wall_s"] for r in runs) for w, runs in results.items()}
    out["runs"] = {str(w): runs for w, runs in results.items()}
    out["speedup_wall_best"] = best[1] / best[2]
    print(f"speed-up (best wall, 1 vs 2 workers): {out['speedup_wall_best']:.2f}x; load {out['load_before']} -> {out['load_after']}")
    (ROOT / "benchmarks" / "sysid_parallel.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
