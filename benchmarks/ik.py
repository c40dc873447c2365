"""IK speed and accuracy: this solver against scipy SLSQP on the same 200 targets.

The targets are tool-centre poses (grinder) along a smooth random path in configuration
space (FK of configurations within the bending bounds, ~5 mm apart), so every target is
reachable and consecutive targets are close, as on a toolpath. Both solvers get the same
targets, the same warm starts (the previous point's solution) and the same cold start
rules, and evaluate the same forward kinematics (``kinematics_kernels.ArmPose``), so the ratio measures the
algorithm, not the FK code. The baseline is SLSQP with numerical (2-point) gradients on
the squared objective k1²‖ΔP‖² + k2²‖log(R_tipᵀR*)‖² with θ ∈ [0, θmax] (the nearest
thing to the paper's MATLAB fmincon), asked for the same accuracy (ftol = (k1·1e-9 m)²);
its cold start is the straight arm plus the best seed-table starts until one succeeds.
Each solver runs its own passes (warm chain, then cold), as in use; CPU times
(process_time, insensitive to other processes' load) are reported next to wall times,
and the goals are judged on CPU time.

Run from the repository root:
    python benchmarks/ik.py [--points 200] [--orientation full|axis] [--accuracy 200] [--out FILE.json]
Prints one JSON object (and writes it to ``--out``). Timings are per point, medians, in milliseconds.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from continuum_sim import ArmGeometry  # noqa: E402
from continuum_sim import kinematics as kin  # noqa: E402
from continuum_sim.ik import IKOptions, get_solver, solve_ik, solve_path  # noqa: E402
from continuum_sim.kinematics_kernels import ArmPose  # noqa: E402


def targets_along_path(geometry: ArmGeometry, n: int, seed: int, tool_length: float) -> tuple[np.ndarray, np.ndarray]:
    """(n, 4, 4) reachable poses along a smooth curve in bending coordinates, and its w."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, n)[:, None]
    bound = geometry.max_bend.repeat(2) / math.sqrt(2.0) * 0.85
    wa, wb = rng.uniform(-bound, bound), rng.uniform(-bound, bound)
    freq = rng.integers(1, 4, wa.size)
    W = wa + (wb - wa) * s + 0.1 * np.sin(2 * np.pi * s * freq)
    return kin.forward_kinematics_bending(geometry, W, tool_length=tool_length), W


class SLSQPBaseline:
    """scipy SLSQP, numerical gradients, on (θ, φ) with θ ∈ [0, θmax]."""

    def __init__(self, geometry: ArmGeometry, tool_length: float, orientation: str, options: IKOptions):
        self.kernel = ArmPose(geometry, tool_length)
        self.k1, self.k2 = options.position_weight, options.orientation_weight
        self.orientation = orientation
        self.bounds = [(0.0, b) if i % 2 == 0 else (None, None) for i, b in enumerate(geometry.max_bend.repeat(2))]
        self.options = options
        self.evaluations = 0
        # Objective target: (k1·1e-9 m)² = 1e-16, i.e. asked for the same 1e-9 accuracy.
        self.ftol = (options.position_weight * options.position_tolerance) ** 2

    def errors(self, q: np.ndarray, target: np.ndarray) -> tuple[float, float]:
        w = kin.to_bending(q).tolist()
        R, p, _ = self.kernel.pose_jacobian(w, False)
        R = np.array(R).reshape(3, 3)
        ep = float(np.linalg.norm(np.array(p) - target[:3, 3]))
        if self.orientation == "full":
            eo = float(np.linalg.norm(kin.log_so3(R.T @ target[:3, :3])))
        else:
            a, b = R[:, 2], target[:3, 2]
            eo = math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))
        return ep, eo

    def objective(self, q: np.ndarray, target: np.ndarray) -> float:
        self.evaluations += 1
        ep, eo = self.errors(q, target)
        return (self.k1 * ep) ** 2 + (self.k2 * eo) ** 2

    def solve(self, target: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, float, float, bool]:
        res = minimize(self.objective, q0, args=(target,), method="SLSQP", bounds=self.bounds,
                       options={"ftol": self.ftol, "maxiter": 500})
        ep, eo = self.errors(res.x, target)
        ok = ep <= self.options.position_tolerance and eo <= self.options.orientation_tolerance
        return res.x, ep, eo, ok


def _stats(wall, cpu, errs_p, errs_o, oks) -> dict:
    return {
        "median_ms": round(1000 * float(np.median(wall)), 4),
        "median_cpu_ms": round(1000 * float(np.median(cpu)), 4),
        "mean_ms": round(1000 * float(np.mean(wall)), 4),
        "success_rate": float(np.mean(oks)),
        "position_error_max_m": float(np.max(errs_p)),
        "orientation_error_max_rad": float(np.max(errs_o)),
        "position_error_median_m": float(np.median(errs_p)),
    }


class _Timer:
    def __enter__(self):
        self.w, self.c = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall, self.cpu = time.perf_counter() - self.w, time.process_time() - self.c


def run(points: int, orientation: str, seed: int, baseline_cold_starts: int, skip_baseline: bool = False) -> dict:
    """Each solver in its own pass over the targets (warm chain, then cold), as in use."""
    geometry = ArmGeometry.default()
    tool = geometry.tools.grinder_length
    options = IKOptions()
    targets, W = targets_along_path(geometry, points, seed, tool)
    spacing = np.linalg.norm(np.diff(targets[:, :3, 3], axis=0), axis=1)
    q_first = kin.from_bending(W[0])
    solver = get_solver(geometry, orientation, "free", tool, 0.0, options)
    seeds = solver.seed_table()[0]  # built once, not timed
    out: dict = {
        "targets": points,
        "orientation": orientation,
        "phase": "free",
        "tool": "grinder",
        "target_spacing_mm_median": round(float(1000 * np.median(spacing)), 3),
        "tolerances": {"position_m": options.position_tolerance, "orientation_rad": options.orientation_tolerance},
        "timing": "per point; wall = perf_counter, cpu = process_time (insensitive to other processes' load)",
    }

    def ours(warm: bool) -> dict:
        wall, cpu, ep, eo, ok = [], [], [], [], []
        q = q_first
        for T in targets:
            with _Timer() as tm:
                res = solve_ik(geometry, T, orientation, "free", q0=q if warm else None, tool=tool, options=options)
            wall.append(tm.wall), cpu.append(tm.cpu), ep.append(res.position_error), eo.append(res.orientation_error)
            ok.append(res.success)
            q = res.q
        return _stats(wall, cpu, ep, eo, ok)

    ours_warm = ours(True)
    ours_cold = ours(False)
    with _Timer() as tm:
        path = solve_path(geometry, targets, q_first, orientation, "free", tool=tool, options=options)
    out["this_solver"] = {
        "warm": ours_warm,
        "cold": ours_cold,
        "path": {
            "note": "solve_path: warm start plus first-order predictor, step limits checked",
            "per_point_ms": round(1000 * tm.wall / max(len(path.q), 1), 4),
            "per_point_cpu_ms": round(1000 * tm.cpu / max(len(path.q), 1), 4),
            "success": bool(path.success),
            "solved_points": int(len(path.q)),
            "position_error_max_m": float(path.position_error.max()),
            "orientation_error_max_rad": float(path.orientation_error.max()),
        },
    }
    if skip_baseline:
        return out

    base = SLSQPBaseline(geometry, tool, orientation, options)

    def theirs(warm: bool) -> dict:
        wall, cpu, ep, eo, ok, evals = [], [], [], [], [], []
        q = q_first
        for T in targets:
            base.evaluations = 0
            with _Timer() as tm:
                if warm:
                    q, e1, e2, good = base.solve(T, q)
                else:
                    starts = [np.zeros(6)] + [kin.from_bending(seeds[i])
                                              for i in solver._seed_order(T)[: baseline_cold_starts - 1]]
                    best = None
                    for q_start in starts:
                        qs, b1, b2, bgood = base.solve(T, q_start)
                        score = (options.position_weight * b1) ** 2 + (options.orientation_weight * b2) ** 2
                        if best is None or score < best[0]:
                            best = (score, b1, b2, bgood)
                        if bgood:
                            break
                    _, e1, e2, good = best
            wall.append(tm.wall), cpu.append(tm.cpu), ep.append(e1), eo.append(e2), ok.append(good)
            evals.append(base.evaluations)
        d = _stats(wall, cpu, ep, eo, ok)
        d["median_function_evaluations"] = float(np.median(evals))
        return d

    out["baseline_slsqp"] = {"warm": theirs(True), "cold": theirs(False)}
    a, b = out["this_solver"], out["baseline_slsqp"]
    out["speed_ratio_warm"] = round(b["warm"]["median_ms"] / a["warm"]["median_ms"], 2)
    out["speed_ratio_warm_cpu"] = round(b["warm"]["median_cpu_ms"] / a["warm"]["median_cpu_ms"], 2)
    out["speed_ratio_cold"] = round(b["cold"]["median_ms"] / a["cold"]["median_ms"], 2)
    out["goal"] = {
        "warm_median_ms_le_0.5": a["warm"]["median_cpu_ms"] <= 0.5,
        "ratio_warm_ge_30": out["speed_ratio_warm_cpu"] >= 30.0,
        "accuracy_equal_or_better": a["warm"]["position_error_max_m"] <= max(b["warm"]["position_error_max_m"], 1e-9)
        and a["warm"]["success_rate"] >= b["warm"]["success_rate"],
    }
    return out


def accuracy(n: int, seed: int) -> dict:
    """Cold solves of FK poses of random configurations in all four modes (planar: φ ∈ {0, π})."""
    geometry = ArmGeometry.default()
    rng = np.random.default_rng(seed)
    out = {}
    for orientation in ("full", "axis"):
        for phase in ("free", "planar"):
            q = np.empty((n, 6))
            q[:, 0::2] = rng.uniform(0.0, 1.0, (n, 3)) * geometry.max_bend
            q[:, 1::2] = rng.uniform(-np.pi, np.pi, (n, 3)) if phase == "free" else \
                np.where(rng.uniform(size=(n, 3)) < 0.5, 0.0, np.pi)
            targets = kin.tool_centre_pose(geometry, q, "grinder")
            ep, eo, ok, cpu = [], [], [], []
            for T in targets:
                with _Timer() as tm:
                    res = solve_ik(geometry, T, orientation, phase, tool="grinder")
                ep.append(res.position_error), eo.append(res.orientation_error), ok.append(res.success)
                cpu.append(tm.cpu)
            out[f"{orientation}/{phase}"] = {
                "targets": n,
                "success_rate": float(np.mean(ok)),
                "position_error_max_m": float(np.max(ep)),
                "orientation_error_max_rad": float(np.max(eo)),
                "cold_median_cpu_ms": round(1000 * float(np.median(cpu)), 4),
            }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--points", type=int, default=200)
    parser.add_argument("--orientation", choices=["full", "axis"], default="full")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--baseline-cold-starts", type=int, default=4)
    parser.add_argument("--skip-baseline", action="store_true", help="time this solver only")
    parser.add_argument("--accuracy", type=int, default=0, metavar="N",
                        help="also solve N random FK poses cold in each of the four modes")
    parser.add_argument("--out", type=Path, help="also write the JSON object to this file")
    args = parser.parse_args()
    result = run(args.points, args.orientation, args.seed, args.baseline_cold_starts, args.skip_baseline)
    if args.accuracy:
        result["accuracy_random_poses"] = accuracy(args.accuracy, args.seed)
    text = json.dumps(result, indent=2)
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
