"""IK speed and accuracy: this solver against scipy SLSQP on the same 200 targets.

The targets are tool-centre poses (grinder) along a smooth random path in configuration
space (FK of configurations within the bending bounds, ~5 mm apart), so every target is
reachable and consecutive targets are close, as on a toolpath. Both solvers get the same
targets, the same warm starts (the previous point's solution) and the same cold start
rules, and evaluate the same forward kinematics (``ArmKernel``), so the ratio measures the
algorithm, not the FK code. The baseline is SLSQP with numerical (2-point) gradients on
the squared objective k1²‖ΔP‖² + k2²‖log(R_tipᵀR*)‖² with θ ∈ [0, θmax] (the nearest
thing to the paper's MATLAB fmincon); its cold start is the straight arm plus the same
seed-table starts until one succeeds.

Run from the repository root:  python benchmarks/ik.py [--points 200] [--orientation full]
Prints one JSON object. Timings are per point, medians, in milliseconds.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from continuum_sim import ArmGeometry  # noqa: E402
from continuum_sim import kinematics as kin  # noqa: E402
from continuum_sim.ik import IKOptions, get_solver, solve_ik, solve_path  # noqa: E402


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
        self.kernel = kin.ArmKernel(geometry, tool_length)
        self.k1, self.k2 = options.position_weight, options.orientation_weight
        self.orientation = orientation
        self.bounds = [(0.0, b) if i % 2 == 0 else (None, None) for i, b in enumerate(geometry.max_bend.repeat(2))]
        self.options = options
        self.evaluations = 0

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
                       options={"ftol": 1e-20, "maxiter": 500})
        ep, eo = self.errors(res.x, target)
        ok = ep <= self.options.position_tolerance and eo <= self.options.orientation_tolerance
        return res.x, ep, eo, ok


def run(points: int, orientation: str, seed: int, baseline_cold_starts: int, skip_baseline: bool = False) -> dict:
    geometry = ArmGeometry.default()
    tool = geometry.tools.grinder_length
    options = IKOptions()
    targets, W = targets_along_path(geometry, points, seed, tool)
    spacing = np.linalg.norm(np.diff(targets[:, :3, 3], axis=0), axis=1)
    q_first = kin.from_bending(W[0])
    out: dict = {
        "targets": points,
        "orientation": orientation,
        "phase": "free",
        "tool": "grinder",
        "target_spacing_mm_median": round(float(1000 * np.median(spacing)), 3),
        "tolerances": {"position_m": options.position_tolerance, "orientation_rad": options.orientation_tolerance},
    }

    def summarise(times, errs_p, errs_o, oks):
        return {
            "median_ms": round(1000 * float(np.median(times)), 4),
            "mean_ms": round(1000 * float(np.mean(times)), 4),
            "success_rate": float(np.mean(oks)),
            "position_error_max_m": float(np.max(errs_p)),
            "orientation_error_max_rad": float(np.max(errs_o)),
            "position_error_median_m": float(np.median(errs_p)),
        }

    # ---- this solver: warm (previous solution), cold (no q0), and along the path.
    get_solver(geometry, orientation, "free", tool, 0.0, options).seed_table()  # build once, not timed
    ours = {}
    for mode in ("warm", "cold"):
        times, ep, eo, ok = [], [], [], []
        q = q_first
        for T in targets:
            t0 = time.perf_counter()
            res = solve_ik(geometry, T, orientation, "free", q0=q if mode == "warm" else None, tool=tool, options=options)
            times.append(time.perf_counter() - t0)
            ep.append(res.position_error), eo.append(res.orientation_error), ok.append(res.success)
            q = res.q
        ours[mode] = summarise(times, ep, eo, ok)
    t0 = time.perf_counter()
    path = solve_path(geometry, targets, q_first, orientation, "free", tool=tool, options=options)
    elapsed = time.perf_counter() - t0
    ours["path"] = {
        "per_point_ms": round(1000 * elapsed / max(len(path.q), 1), 4),
        "success": bool(path.success),
        "solved_points": int(len(path.q)),
        "position_error_max_m": float(path.position_error.max()),
        "orientation_error_max_rad": float(path.orientation_error.max()),
    }
    out["this_solver"] = ours

    if skip_baseline:
        return out
    # ---- baseline
    base = SLSQPBaseline(geometry, tool, orientation, options)
    solver = get_solver(geometry, orientation, "free", tool, 0.0, options)
    seeds = solver.seed_table()[0]
    theirs = {}
    for mode in ("warm", "cold"):
        times, ep, eo, ok, evals = [], [], [], [], []
        q = q_first
        for T in targets:
            base.evaluations = 0
            t0 = time.perf_counter()
            if mode == "warm":
                q, e1, e2, good = base.solve(T, q)
            else:
                starts = [np.zeros(6)] + [kin.from_bending(seeds[i]) for i in solver._seed_order(T)[: baseline_cold_starts - 1]]
                best = None
                for q_start in starts:
                    qs, e1, e2, good = base.solve(T, q_start)
                    score = (options.position_weight * e1) ** 2 + (options.orientation_weight * e2) ** 2
                    if best is None or score < best[0]:
                        best = (score, qs, e1, e2, good)
                    if good:
                        break
                _, q, e1, e2, good = best
            times.append(time.perf_counter() - t0)
            ep.append(e1), eo.append(e2), ok.append(good), evals.append(base.evaluations)
        theirs[mode] = summarise(times, ep, eo, ok)
        theirs[mode]["median_function_evaluations"] = float(np.median(evals))
    out["baseline_slsqp"] = theirs
    out["speed_ratio_warm"] = round(theirs["warm"]["median_ms"] / ours["warm"]["median_ms"], 2)
    out["speed_ratio_cold"] = round(theirs["cold"]["median_ms"] / ours["cold"]["median_ms"], 2)
    out["goal"] = {
        "warm_median_ms_le_0.5": ours["warm"]["median_ms"] <= 0.5,
        "ratio_warm_ge_30": out["speed_ratio_warm"] >= 30.0,
        "accuracy_equal_or_better": ours["warm"]["position_error_max_m"] <= max(theirs["warm"]["position_error_max_m"], 1e-9)
        and ours["warm"]["success_rate"] >= theirs["warm"]["success_rate"],
    }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--points", type=int, default=200)
    parser.add_argument("--orientation", choices=["full", "axis"], default="full")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--baseline-cold-starts", type=int, default=4)
    parser.add_argument("--skip-baseline", action="store_true", help="time this solver only")
    args = parser.parse_args()
    print(json.dumps(run(args.points, args.orientation, args.seed, args.baseline_cold_starts, args.skip_baseline), indent=2))


if __name__ == "__main__":
    main()
