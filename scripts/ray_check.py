"""A 60-trial optimisation on a two-node Ray cluster: it connects once and records what the local run records.

    python scripts/ray_check.py --out docs/optimize/ray_check.json [--spec studies/optimize_open_loop_quick_tpe.toml]

The gravity-hold study (TPE, 60 designs, seed fixed by the spec) runs twice from the CLI,
in temporary folders: locally (``--workers 2``), then on a two-node loopback cluster with
token authentication (a head and a second node, one CPU each, 127.0.0.1 only:
``scripts/ray_loopback.py``, the cluster of tests/test_ray_cluster.py) through
``--backend ray --address 127.0.0.1:PORT``. Written: the trial count, how many ``ray:
connected to`` lines the Ray run printed (one per study: the ten generations share one
connection and one set of warm workers), whether the two ``trials.csv`` are identical (every
column but ``cpu_s``, compared as written: parameters and objective values to the last
digit), the wall time of each run, the Ray workers' start-up (``worker_startup_s``, not part
of any evaluation) and the cluster's start. Exit 0 when the runs are identical with one
connection, 1 otherwise (the JSON is written either way). The cluster is stopped in a finally.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from ray_loopback import ROOT, driver_env, loopback_cluster  # noqa: E402

SPEC = "studies/optimize_open_loop_quick_tpe.toml"
TIMING = ("cpu_s",)  # trials.csv columns that measure the run, not its result


def run_cli(spec: str, out: Path, env: dict[str, str], *extra: str) -> tuple[float, subprocess.CompletedProcess]:
    cmd = [sys.executable, "-m", "continuum_sim", "optimize", spec, "--out", str(out), "--quiet", *extra]
    start = time.perf_counter()
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=1800)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"ray_check: {' '.join(cmd[2:])} exited {done.returncode}: {done.stderr.strip()[-1500:]}")
    return wall, done


def trial_rows(folder: Path) -> list[dict[str, str]]:
    with (folder / "trials.csv").open(newline="") as fh:
        return [{k: v for k, v in row.items() if k not in TIMING} for row in csv.DictReader(fh)]


def differences(a: list[dict[str, str]], b: list[dict[str, str]]) -> list[str]:
    if len(a) != len(b):
        return [f"{len(a)} trials locally, {len(b)} on Ray"]
    out = []
    for ra, rb in zip(a, b):
        for key in sorted(set(ra) | set(rb)):
            if ra.get(key) != rb.get(key):
                out.append(f"trial {ra.get('trial')}: {key}: {ra.get(key)!r} locally, {rb.get(key)!r} on Ray")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spec", default=SPEC)
    parser.add_argument("--out", required=True, help="the JSON to write")
    parser.add_argument("--local-workers", type=int, default=2, help="the local run's workers (the cluster has 2 CPUs)")
    args = parser.parse_args(argv)
    import ray

    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="ray_check_") as tmp:
        local_dir, ray_dir = Path(tmp) / "local", Path(tmp) / "ray"
        local_wall, _ = run_cli(args.spec, local_dir, driver_env(), "--workers", str(args.local_workers))
        print(f"local ({args.local_workers} workers): {local_wall:.1f} s", file=sys.stderr)
        with loopback_cluster(cpus_per_node=1) as cluster:
            print(f"cluster up at {cluster.address} in {cluster.start_s:.1f} s", file=sys.stderr)
            ray_wall, done = run_cli(args.spec, ray_dir, cluster.env, "--backend", "ray", "--address", cluster.address)
            address = cluster.address
        print(f"ray (2 nodes x 1 CPU): {ray_wall:.1f} s", file=sys.stderr)
        stderr_lines = done.stderr.splitlines()
        connected = [line for line in stderr_lines if "ray: connected to" in line]
        local_rows, ray_rows = trial_rows(local_dir), trial_rows(ray_dir)
        diffs = differences(local_rows, ray_rows)
        summary = json.loads((ray_dir / "summary.json").read_text())
        local_summary = json.loads((local_dir / "summary.json").read_text())
        result = {
            "spec": args.spec,
            "sampler": summary.get("sampler"),
            "seed": summary.get("seed"),
            "trials": len(ray_rows),
            "evaluations": summary.get("evaluations"),
            "connections": len(connected),
            "connected_line": connected[0].replace(address, "127.0.0.1:PORT") if connected else None,
            "identical": not diffs and len(local_rows) == len(ray_rows) > 0,
            "compared": "trials.csv, every column but cpu_s, as written (parameters, objectives, feasibility, failures)",
            "differences": diffs[:20],
            "local_workers": args.local_workers,
            "local_wall_s": round(local_wall, 2),
            "ray_wall_s": round(ray_wall, 2),
            "worker_startup_s": summary.get("worker_startup_s"),
            "cluster_start_s": round(cluster.start_s, 2),
            "local_cpu_s": local_summary.get("cpu_s"),
            "ray_cpu_s": summary.get("cpu_s"),
            "cluster": {"nodes": cluster.nodes, "cpus_per_node": cluster.cpus_per_node, "address": "127.0.0.1 (loopback only)",
                        "authentication": "token (RAY_AUTH_MODE=token on the nodes; the driver gets RAY_AUTH_TOKEN only)",
                        "stray_processes_killed": len(cluster.strays_killed)},
            "ray_stderr": [line.replace(address, "127.0.0.1:PORT") for line in stderr_lines if line.startswith("ray:")],
            "machine": {"cpus": os.cpu_count(), "loadavg_before": [round(x, 2) for x in load_before],
                        "loadavg_after": [round(x, 2) for x in os.getloadavg()], "ray": ray.__version__,
                        "python": platform.python_version()},
        }
    text = json.dumps(result, indent=2)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text + "\n")
    print(text)
    return 0 if result["identical"] and result["connections"] == 1 else 1


if __name__ == "__main__":
    sys.exit(main())
