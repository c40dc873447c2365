"""Design-study throughput benchmark; prints JSON (and writes it with --out).

    python benchmarks/optimize.py [--trials 16] [--batch 8] [--settle 8.0] [--repeats 2]

The same seeded NSGA-II study (two design variables, the open-loop gravity hold as the
evaluation) run with 1 and 2 local workers, alternated round by round so the machine's
load drifts hit both alike; each figure is the best of ``--repeats`` rounds. Reported:
evaluations per hour (wall), the ratio 2 workers / 1 worker (goal >= 1.8), CPU per
evaluation in the workers, the driver's own CPU (Optuna's ask/tell, the journal, records,
report) and the cores the study actually got (worker CPU / wall: below the worker count
when other load holds the cores). Every round is a fresh study folder, so the numbers
include the pool's start, and both worker counts must give the same trials.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from continuum_sim.optimize import parse_spec, run_study  # noqa: E402


def make_spec(trials: int, batch: int, settle: float):
    return parse_spec(
        {
            "variables": {
                "model.stiffness_scale": {"low": 0.5, "high": 4.0, "log": True},
                "control.pretension": {"low": 15.0, "high": 50.0},
            },
            "objectives": [{"metric": "sag_mm"}, {"metric": "max_cable_tension_n"}],
            "optimizer": {"sampler": "nsga2", "trials": trials, "batch": batch, "seed": 0},
            "evaluation": {"kind": "gravity_sag", "settle_s": settle},
        }
    )


def one_run(spec, workers: int, folder: Path) -> dict:
    wall, cpu = time.perf_counter(), time.process_time()
    result = run_study(spec, folder, workers=workers, progress=False)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    records = [json.loads(p.read_text()) for p in (folder / "evaluations" / "records").glob("*.json")]
    worker_cpu = sum(r["cpu_s"] or 0.0 for r in records)
    with (folder / "trials.csv").open() as fh:
        trials = [(row["model.stiffness_scale"], row["control.pretension"], row["sag_mm"]) for row in csv.DictReader(fh)]
    return {"wall_s": wall, "driver_cpu_s": cpu, "worker_cpu_s": worker_cpu, "evaluations": result.n_evaluated, "trials": trials}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=16)
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--settle", type=float, default=8.0, help="simulated s per phase of the gravity hold")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--out", help="also write the JSON here")
    args = parser.parse_args()
    spec = make_spec(args.trials, args.batch, args.settle)
    load_before = os.getloadavg()
    runs: dict[int, list[dict]] = {1: [], 2: []}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            for workers in (1, 2) if r % 2 == 0 else (2, 1):
                runs[workers].append(one_run(spec, workers, Path(tmp) / f"w{workers}_r{r}"))
                print(f"round {r}, {workers} worker(s): {runs[workers][-1]['wall_s']:.1f} s", file=sys.stderr)
    best = {w: min(rs, key=lambda x: x["wall_s"]) for w, rs in runs.items()}
    per_hour = {w: 3600.0 * b["evaluations"] / b["wall_s"] for w, b in best.items()}
    out = {
        "machine": {"cpus": os.cpu_count(), "loadavg_before": load_before, "loadavg_after": os.getloadavg(),
                    "note": "shared machine: other jobs' load is in loadavg; cores_used says what the study got"},
        "workload": {"trials": args.trials, "batch": args.batch, "evaluation": f"gravity_sag, settle_s = {args.settle}",
                     "sampler": "nsga2", "repeats": args.repeats},
        "workers": {
            str(w): {
                "evaluations_per_hour": per_hour[w],
                "wall_s": b["wall_s"],
                "worker_cpu_s_per_evaluation": b["worker_cpu_s"] / b["evaluations"],
                "driver_cpu_s": b["driver_cpu_s"],
                "cores_used": b["worker_cpu_s"] / b["wall_s"],
                "raw_wall_s": [round(x["wall_s"], 2) for x in runs[w]],
            }
            for w, b in best.items()
        },
        "speedup_2_over_1": per_hour[2] / per_hour[1],
        "same_trials": all(x["trials"] == runs[1][0]["trials"] for rs in runs.values() for x in rs),
    }
    text = json.dumps(out, indent=2)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")


if __name__ == "__main__":
    main()
