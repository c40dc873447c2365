"""Design-study throughput: local 1 worker, local 2 workers and a two-node Ray cluster, interleaved; prints JSON (--out writes it).

    python benchmarks/optimize.py [--spec studies/optimize_open_loop.toml] [--trials 8] [--batch 4] [--repeats 2] [--out FILE]

The same seeded study, a shipped spec with a smaller trial budget (default: study 1, the open
loop over the whole task, ~5 s CPU per design; ``--spec studies/optimize_open_loop_quick_tpe.toml``
for the gravity-hold twin, ~0.5 s), run in-process by ``run_study`` in three set-ups:

* ``local_1``, ``local_2``: the local backend (forkserver pool) with 1 and 2 workers;
* ``ray_2x1``: ``--backend ray --address`` on a two-node loopback cluster with token
  authentication (a head and a second node, one CPU each, 127.0.0.1 only:
  ``scripts/ray_loopback.py``), started once before the rounds (its start is reported apart).

Round r runs the three set-ups in a rotated order, so the shared machine's load drifts hit all
alike; each figure is the best of ``--repeats`` rounds. Every round is a fresh study folder, so
the numbers include starting the pool or the Ray workers (``worker_startup_s``, reported apart
too), one connection per study. Reported per set-up: evaluations per hour (wall), CPU per
evaluation in the workers, the bytes each evaluation's record and each trial's journal entries
take, the driver's own CPU (Optuna's ask/tell, the journal, records,
report; with Ray also the driver's Ray client threads), the cores the study actually got
(worker CPU / wall: below the worker count when other load holds the cores) and the load
average before and after. All set-ups must give the same trials (``same_trials``).

Then the driver alone (``driver``): the study's ask/tell on its journal, ``--driver-trials``
designs in generations of ``--driver-batch`` with stand-in objective values and no
simulation: its CPU per trial as the told history grows, and the journal's bytes per trial
(what limits one driver feeding a large cluster: docs/optimize.md, throughput and scale).
"""

from __future__ import annotations

import csv
import json
import os
import platform
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

import argparse  # noqa: E402

from continuum_sim.optimize import parse_spec, run_study  # noqa: E402

SETUPS = ("local_1", "local_2", "ray_2x1")


def make_spec(path: str, trials: int, batch: int):
    """The spec at ``path`` with ``optimizer.trials`` and ``optimizer.batch`` replaced (seed and sampler kept)."""
    text = (ROOT / path).read_text()
    data = tomllib.loads(text)
    data["optimizer"] = dict(data.get("optimizer", {}), trials=trials, batch=batch)
    return parse_spec(data, (ROOT / path).parent, text), data


def one_run(spec, setup: str, folder: Path, address: str | None, ray_env: dict[str, str]) -> dict:
    saved = dict(os.environ)
    if setup.startswith("ray"):
        os.environ.update(ray_env)  # the token and loopback settings, for this study's driver only
    load = os.getloadavg()[0]
    wall, cpu = time.perf_counter(), time.process_time()
    try:
        if setup.startswith("ray"):
            result = run_study(spec, folder, backend="ray", address=address, progress=False)
        else:
            result = run_study(spec, folder, workers=int(setup.split("_")[1]), progress=False)
    finally:
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        os.environ.clear()
        os.environ.update(saved)
    paths = list((folder / "evaluations" / "records").glob("*.json"))
    records = [json.loads(p.read_text()) for p in paths]
    record_bytes = sum(p.stat().st_size for p in paths) / max(1, len(paths))
    journal = folder / "study.journal"
    journal_bytes = journal.stat().st_size if journal.is_file() else None
    worker_cpu = sum(r["cpu_s"] or 0.0 for r in records)
    summary = json.loads((folder / "summary.json").read_text())
    with (folder / "trials.csv").open() as fh:
        trials = [{k: v for k, v in row.items() if k != "cpu_s"} for row in csv.DictReader(fh)]
    return {"wall_s": wall, "driver_cpu_s": cpu, "worker_cpu_s": worker_cpu, "evaluations": result.n_evaluated,
            "worker_startup_s": summary.get("worker_startup_s"), "loadavg_1min_before": load, "trials": trials,
            "record_bytes": record_bytes, "journal_bytes": journal_bytes}


def driver_costs(spec, folder: Path) -> dict:
    """The driver's own work per trial as the history grows: the study's ask (a sampler made per trial, seeded), its
    re-suggest and tell, on the study's journal storage, with stand-in objective values (no simulation)."""
    import math

    import optuna

    from continuum_sim.optimize.study import make_sampler, open_study, suggest

    folder.mkdir(parents=True, exist_ok=True)
    study = open_study(spec, folder)
    batch, rows = spec.optimizer.batch, []
    for n in range(0, spec.optimizer.trials, batch):
        t0 = time.process_time()
        for number in range(n, n + batch):
            study.sampler = make_sampler(spec, number)
            suggest(spec, study.ask())
        t1 = time.process_time()
        running = [t for t in study.get_trials(deepcopy=False) if t.state == optuna.trial.TrialState.RUNNING]
        for t in running:
            study.sampler = make_sampler(spec, t.number)
            x = list(suggest(spec, optuna.trial.Trial(study, t._trial_id)).values())
            study.tell(t.number, [1.0 + sum(math.log(abs(v) + 1.0) for v in x[:-1]) ** 2, 3.0 * x[-1]][: len(spec.objectives)])
        t2 = time.process_time()
        rows.append({"told_before": n, "ask_ms_per_trial": round(1000 * (t1 - t0) / batch, 2),
                     "tell_ms_per_trial": round(1000 * (t2 - t1) / batch, 2)})
        print(f"driver: {n} told, ask {rows[-1]['ask_ms_per_trial']} ms, tell {rows[-1]['tell_ms_per_trial']} ms per trial",
              file=sys.stderr)
    journal = folder / "study.journal"
    return {"trials": spec.optimizer.trials, "batch": batch, "sampler": spec.optimizer.sampler, "generations": rows,
            "journal_bytes_per_trial": round(journal.stat().st_size / spec.optimizer.trials),
            "note": "CPU of the study's ask/tell on its journal, stand-in objective values, no evaluation"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spec", default="studies/optimize_open_loop.toml", help="a shipped optimisation spec")
    parser.add_argument("--trials", type=int, default=8)
    parser.add_argument("--batch", type=int, default=4, help="designs per generation (ask/tell round)")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--driver-trials", type=int, default=1024, help="trials of the driver-only ask/tell measurement")
    parser.add_argument("--driver-batch", type=int, default=256)
    parser.add_argument("--out", help="also write the JSON here")
    args = parser.parse_args()
    from ray_loopback import LOOPBACK, loopback_cluster

    spec, data = make_spec(args.spec, args.trials, args.batch)
    load_before = os.getloadavg()
    runs: dict[str, list[dict]] = {s: [] for s in SETUPS}
    # Ray reads the loopback setting once, when it is imported (in the first Ray study): without it the driver maps
    # 127.0.0.1 to the machine's outward address and never reaches the cluster.
    os.environ.update(LOOPBACK)
    with tempfile.TemporaryDirectory() as tmp, loopback_cluster(cpus_per_node=1) as cluster:
        ray_env = {k: v for k, v in cluster.env.items() if k.startswith("RAY_AUTH")}
        print(f"cluster: 2 nodes x 1 CPU at {cluster.address}, up in {cluster.start_s:.1f} s", file=sys.stderr)
        for r in range(args.repeats):
            order = SETUPS[r % 3:] + SETUPS[:r % 3]
            for setup in order:
                runs[setup].append(one_run(spec, setup, Path(tmp) / f"{setup}_r{r}", cluster.address, ray_env))
                print(f"round {r}, {setup}: {runs[setup][-1]['wall_s']:.1f} s", file=sys.stderr)
        cluster_start_s = cluster.start_s
        driver_spec, _ = make_spec(args.spec, args.driver_trials, args.driver_batch)
        driver = driver_costs(driver_spec, Path(tmp) / "driver")
    import ray

    best = {s: min(rs, key=lambda x: x["wall_s"]) for s, rs in runs.items()}
    per_hour = {s: 3600.0 * b["evaluations"] / b["wall_s"] for s, b in best.items()}
    evaluation = data.get("evaluation", {"kind": "scenario"})
    out = {
        "machine": {"cpus": os.cpu_count(), "loadavg_before": [round(x, 2) for x in load_before],
                    "loadavg_after": [round(x, 2) for x in os.getloadavg()], "python": platform.python_version(),
                    "ray": ray.__version__,
                    "note": "shared machine: other jobs' load is in loadavg; cores_used says what the study got"},
        "workload": {"spec": args.spec, "trials": args.trials, "batch": args.batch, "generations": -(-args.trials // args.batch),
                     "evaluation": evaluation.get("kind", "scenario"),
                     "control_mode": data.get("config", {}).get("control", {}).get("mode"),
                     "sampler": data["optimizer"].get("sampler"),
                     "seed": data["optimizer"].get("seed"), "repeats": args.repeats},
        "cluster": {"nodes": 2, "cpus_per_node": 1, "address": "127.0.0.1 (loopback)", "authentication": "token",
                    "start_s": round(cluster_start_s, 2)},
        "setups": {
            s: {
                "workers": 2 if s != "local_1" else 1,
                "evaluations": b["evaluations"],
                "evaluations_per_hour": per_hour[s],
                "wall_s": b["wall_s"],
                "worker_cpu_s_per_evaluation": b["worker_cpu_s"] / b["evaluations"],
                "driver_cpu_s": b["driver_cpu_s"],
                "driver_cpu_s_per_generation": b["driver_cpu_s"] / -(-args.trials // args.batch),
                "worker_startup_s": b["worker_startup_s"],
                "cores_used": b["worker_cpu_s"] / b["wall_s"],
                "loadavg_1min_before": round(b["loadavg_1min_before"], 2),
                "raw_wall_s": [round(x["wall_s"], 2) for x in runs[s]],
                "record_bytes_per_evaluation": round(b["record_bytes"]),
                "journal_bytes_per_trial": round(b["journal_bytes"] / args.trials) if b["journal_bytes"] else None,
            }
            for s, b in best.items()
        },
        "speedup_local_2_over_1": per_hour["local_2"] / per_hour["local_1"],
        "speedup_ray_2x1_over_local_1": per_hour["ray_2x1"] / per_hour["local_1"],
        "driver": driver,
        "same_trials": all(x["trials"] == runs["local_1"][0]["trials"] for rs in runs.values() for x in rs),
    }
    text = json.dumps(out, indent=2)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")


if __name__ == "__main__":
    main()
