"""How far the default run's metrics drift between CPU targets and BLAS kernels; the tolerances that follow.

Runs the default scenario (``run_scenario(ScenarioConfig.default())``, no video) once per
*target*, each in its own process with its own environment:

- numba's code generation: the host CPU (``NUMBA_CPU_NAME`` unset), ``generic`` (baseline
  x86-64: no AVX, no FMA), ``haswell`` (AVX2 + FMA); each with a fresh ``NUMBA_CACHE_DIR``
  (numba's cache is keyed by CPU, a fresh folder makes sure nothing compiled for another
  target is loaded);
- OpenBLAS's kernels (numpy's and scipy's bundled OpenBLAS, ``DYNAMIC_ARCH``): every core
  type ``OPENBLAS_CORETYPE`` selects on this machine (``OPENBLAS_VERBOSE=2`` prints the core
  chosen; the script records it), and ``OPENBLAS_NUM_THREADS=1`` against the default;
- a worst case: numba ``generic`` with the oldest OpenBLAS core.

It prints, per metric leaf (``scenario.metric_compare.flatten``), the largest absolute and
relative difference from the first target (the host) and from the stored reference, and with
``--write`` stores ``tests/data/reference_tolerance.json``:

    atol = max(MARGIN x largest |difference| measured, REL_FLOOR x |reference|, ABS_FLOOR)

(plus a per-metric floor for quantities on a grid, e.g. times on the 4 ms step). Outcome leaves
(booleans, integers, strings) are reported and must not differ at all.

    python scripts/drift_study.py --write          # ~1 min CPU per target (the first per numba target compiles)
    python scripts/drift_study.py --targets host,numba-generic --jobs 2
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from continuum_sim.scenario.metric_compare import flatten, is_continuous  # noqa: E402

DATA = ROOT / "tests" / "data"
MARGIN = 10.0  # tolerance = MARGIN x the largest drift measured here (other machines may drift further)
REL_FLOOR = 1e-6  # ... but never below this fraction of the reference value (a metric that did not drift here may elsewhere)
ABS_FLOOR = 1e-9  # ... nor below this, in the metric's unit (values that are zero up to rounding: 1e-12 mm tip errors)
QUANTUM_FLOORS = {  # quantities on a grid move by whole steps when they move
    "detach_time_s": 0.004,  # the 4 ms time step
    "sim_seconds": 0.004,
}
# A drift seen on another machine (the issue that asked for this study): cutting error mean 0.06050932 mm
# there against 0.06050770 mm stored. The tolerance must cover it.
SEEN_ELSEWHERE = {"cutting_tip_error_mm.mean": abs(0.06050932 - 0.06050770)}

# name -> (numba CPU name or "" for the host, environment overrides). OPENBLAS_CORETYPE="" lets OpenBLAS detect the host.
TARGETS: dict[str, tuple[str, dict[str, str]]] = {
    "host": ("", {}),
    "numba-generic": ("generic", {}),
    "numba-haswell": ("haswell", {}),
    "blas-skylakex": ("", {"OPENBLAS_CORETYPE": "SkylakeX"}),
    "blas-sandybridge": ("", {"OPENBLAS_CORETYPE": "Sandybridge"}),
    "blas-nehalem": ("", {"OPENBLAS_CORETYPE": "Nehalem"}),
    "blas-prescott": ("", {"OPENBLAS_CORETYPE": "Prescott"}),
    "blas-1thread": ("", {"OPENBLAS_NUM_THREADS": "1"}),
    "generic+nehalem": ("generic", {"OPENBLAS_CORETYPE": "Nehalem", "OPENBLAS_NUM_THREADS": "1"}),
}

RUN = """
import json, sys, time
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.scenario.runner import run_scenario
t = time.process_time()
run_scenario(ScenarioConfig.default(), sys.argv[1])
print("CPU_SECONDS", time.process_time() - t)
"""


def run_target(name: str, caches: Path, work: Path) -> dict[str, Any]:
    """One default run under ``name``'s environment: its metrics, the OpenBLAS core it used, its CPU seconds."""
    cpu, overrides = TARGETS[name]
    env = dict(os.environ, PYTHONPATH=str(ROOT), MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"), OPENBLAS_VERBOSE="2")
    env.pop("NUMBA_CPU_NAME", None)
    if cpu:
        env["NUMBA_CPU_NAME"] = cpu
    env["NUMBA_CACHE_DIR"] = str(caches / (cpu or "host"))
    for key, value in overrides.items():
        if value:
            env[key] = value
        else:
            env.pop(key, None)
    out = work / name
    started = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", RUN, str(out)], env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{name} failed:\n{proc.stderr[-2000:]}")
    cores = sorted(set(re.findall(r"^Core: (\S+)", proc.stdout + proc.stderr, re.M)))
    cpu_s = float(re.findall(r"CPU_SECONDS (\S+)", proc.stdout)[-1])
    return {"target": name, "numba_cpu": cpu or "host", "env": overrides, "openblas_cores": cores,
            "cpu_seconds": cpu_s, "wall_seconds": time.perf_counter() - started,
            "metrics": json.loads((out / "metrics.json").read_text())}


def drift_table(runs: list[dict[str, Any]], reference: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Per leaf: reference value, the largest |difference| from the host run and from the reference, which target."""
    ref = flatten(reference)
    host = flatten(runs[0]["metrics"])
    table: dict[str, dict[str, Any]] = {}
    for path, want in ref.items():
        row: dict[str, Any] = {"reference": want, "continuous": is_continuous(want), "abs_vs_host": 0.0,
                               "abs_vs_reference": 0.0, "worst_target": None, "outcome_differs": []}
        for run in runs:
            got = flatten(run["metrics"]).get(path)
            if is_continuous(want) and isinstance(got, float):
                d_ref, d_host = abs(got - want), abs(got - float(host[path] or 0.0))
                if d_ref > row["abs_vs_reference"]:
                    row["abs_vs_reference"], row["worst_target"] = d_ref, run["target"]
                row["abs_vs_host"] = max(row["abs_vs_host"], d_host)
            elif got != want:
                row["outcome_differs"].append(run["target"])
        if row["continuous"]:
            scale = abs(want) if want else 0.0
            row["rel_vs_reference"] = row["abs_vs_reference"] / scale if scale else 0.0
        table[path] = row
    return table


def target_summary(run: dict[str, Any], host: dict[str, Any], reference: dict[str, Any]) -> dict[str, Any]:
    """One target against the host run and the reference: leaves that differ, the largest relative difference."""
    got, base, ref = flatten(run["metrics"]), flatten(host["metrics"]), flatten(reference)

    def compare(other: dict[str, Any]) -> tuple[int, float]:
        differ = [p for p in ref if got.get(p) != other.get(p)]
        rel = [abs(got[p] - other[p]) / abs(other[p]) for p in differ
               if isinstance(got.get(p), float) and isinstance(other.get(p), float) and abs(other[p]) > 1e-9]
        return len(differ), max(rel, default=0.0)

    (n_host, rel_host), (n_ref, rel_ref) = compare(base), compare(ref)
    return {"leaves_differing_from_host": n_host, "max_rel_vs_host": rel_host,
            "leaves_differing_from_reference": n_ref, "max_rel_vs_reference": rel_ref,
            "cutting_tip_error_mean_mm": run["metrics"]["cutting_tip_error_mm"]["mean"]}


def tolerances(table: dict[str, dict[str, Any]]) -> dict[str, float]:
    """atol per continuous leaf: MARGIN x measured drift, floored (see the module docstring)."""
    atol: dict[str, float] = {}
    for path, row in table.items():
        if not row["continuous"]:
            continue
        measured = max(row["abs_vs_reference"], row["abs_vs_host"], SEEN_ELSEWHERE.get(path, 0.0))
        atol[path] = max(MARGIN * measured, REL_FLOOR * abs(row["reference"]), ABS_FLOOR, QUANTUM_FLOORS.get(path, 0.0))
    return atol


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--targets", default=",".join(TARGETS), help="comma-separated subset of: " + ", ".join(TARGETS))
    parser.add_argument("--jobs", type=int, default=1, help="targets run in parallel (each a single-process run)")
    parser.add_argument("--write", action="store_true", help="store tests/data/reference_tolerance.json")
    parser.add_argument("--json", type=Path, help="also write the full study (runs and table) here")
    args = parser.parse_args()
    names = [n for n in args.targets.split(",") if n]
    unknown = set(names) - set(TARGETS)
    if unknown:
        parser.error(f"unknown target(s) {sorted(unknown)}; choose from {list(TARGETS)}")
    reference = json.loads((DATA / "reference_metrics.json").read_text())
    with tempfile.TemporaryDirectory() as tmp:
        caches, work = Path(tmp) / "numba", Path(tmp) / "runs"
        # The first run per numba target compiles into its fresh cache; run those first, one at a time,
        # so that the rest (BLAS variants on the host cache) load instead of compiling concurrently.
        first = {}
        for n in names:
            first.setdefault(TARGETS[n][0], n)
        order = list(first.values()) + [n for n in names if n not in first.values()]
        runs: dict[str, dict[str, Any]] = {}
        for n in first.values():
            runs[n] = run_target(n, caches, work)
            print(f"{n}: {runs[n]['cpu_seconds']:.1f} s CPU (compiles), OpenBLAS {runs[n]['openblas_cores']}", flush=True)
        rest = [n for n in order if n not in runs]
        with ThreadPoolExecutor(max(1, args.jobs)) as pool:
            for run in pool.map(lambda n: run_target(n, caches, work), rest):
                runs[run["target"]] = run
                print(f"{run['target']}: {run['cpu_seconds']:.1f} s CPU, OpenBLAS {run['openblas_cores']}", flush=True)
    ordered = [runs[n] for n in names]
    table = drift_table(ordered, reference)
    atol = tolerances(table)

    print(f"\n{'metric':58s} {'reference':>14s} {'max |d| vs ref':>14s} {'rel':>9s} {'vs host':>10s}  worst target")
    for path, row in table.items():
        if row["continuous"] and (row["abs_vs_reference"] or row["abs_vs_host"]):
            print(f"{path:58s} {row['reference']:14.7g} {row['abs_vs_reference']:14.3g} {row['rel_vs_reference']:9.2g} "
                  f"{row['abs_vs_host']:10.3g}  {row['worst_target']}")
    steady = sum(1 for r in table.values() if r["continuous"] and not (r["abs_vs_reference"] or r["abs_vs_host"]))
    print(f"({steady} continuous leaves identical in every target)")
    outcomes = {p: r["outcome_differs"] for p, r in table.items() if r["outcome_differs"]}
    print("outcome leaves that differ:", outcomes or "none")
    print(f"\n{'target':18s} {'numba':8s} {'OpenBLAS':12s} {'leaves != host':>14s} {'max rel':>8s} "
          f"{'leaves != ref':>13s} {'max rel':>8s}  cutting error mean (mm)")
    for run in ordered:
        run.update(target_summary(run, ordered[0], reference))
        print(f"{run['target']:18s} {run['numba_cpu']:8s} {','.join(run['openblas_cores']):12s} "
              f"{run['leaves_differing_from_host']:14d} {run['max_rel_vs_host']:8.1g} "
              f"{run['leaves_differing_from_reference']:13d} {run['max_rel_vs_reference']:8.1g}  {run['cutting_tip_error_mean_mm']!r}")

    study = {"command": "python scripts/drift_study.py " + " ".join(sys.argv[1:]),
             "date": time.strftime("%Y-%m-%d", time.gmtime()),
             "margin": MARGIN, "rel_floor": REL_FLOOR, "abs_floor": ABS_FLOOR, "quantum_floors": QUANTUM_FLOORS,
             "seen_elsewhere": SEEN_ELSEWHERE,
             "targets": [{k: v for k, v in r.items() if k != "metrics"} for r in ordered]}
    if args.json:
        args.json.write_text(json.dumps({**study, "table": table}, indent=2, sort_keys=True) + "\n")
    if args.write:
        path = DATA / "reference_tolerance.json"
        path.write_text(json.dumps({"how": __doc__.split("\n\n")[0] + " (scripts/drift_study.py)", **study,
                                    "atol": atol}, indent=2, sort_keys=True) + "\n")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
