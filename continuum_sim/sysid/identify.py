"""Identify plant parameters from a recording: least squares over simulated replays.

Any numeric field of the scenario configuration can be fitted, named by its dotted path
(``model.stiffness_scale``, ``model.rope_modulus``, ``model.grinder_mass``,
``arm.sections.1.cable_angles_deg.2``, …), so a parameter a new plant model adds is
fittable without code here. The residuals are the position errors in mm (mean offset
removed when the recording says ``align = offset``) and, when the recording has
orientations, the orientation errors in degrees times ``orientation_weight`` (mm/deg).

The optimiser (scipy ``least_squares``, trust-region reflective, bounded) works on
scaled variables x = (value − initial)/scale; its finite-difference Jacobian columns are
replayed together (one batched ``mujoco.rollout`` call on ``nthread`` threads, or one
process per replay with cable friction). Optionally a seeded Sobol multi-start. The
report (``_report``, ``fit_warnings``) says what the data cannot tell: 95 % intervals
from ``mujoco.sysid.calculate_intervals``, singular values and correlations of J,
parameters the data cannot move, and fits that started or ended on a bound, changed
nothing or stopped on the evaluation limit (``--strict`` turns these into exit 1).
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..configio import (
    ConfigError,
    atomic_write_text,
    dumps_toml,
    get_path,
    replace_path,
    to_dict,
)
from ..scenario.config import ScenarioConfig
from .data import Recording
from .replay import Prediction, marker_point, plot_paths, position_errors, replay_metrics, simulate

MARKER = "arm.tools.marker_offset."

Array = NDArray[np.float64]


@dataclass(frozen=True)
class FitParameter:
    """One fitted path with its bounds."""

    path: str
    initial: float
    low: float
    high: float
    integer: bool = False

    @property
    def scale(self) -> float:
        return abs(self.initial) if self.initial != 0 else (self.high - self.low) / 10.0


def parse_fit(spec: str, config: ScenarioConfig) -> FitParameter:
    """``PATH`` or ``PATH=LOW:HIGH``; checks the path is numeric and both bounds are valid values."""
    path, _, bounds = spec.partition("=")
    path = path.strip()
    where = f"--fit {path}"
    try:
        current = get_path(config, path)
    except ConfigError as exc:
        raise ConfigError(f"--fit {path}", f"unknown parameter path ({exc.field}: {exc.message})") from None
    if isinstance(current, bool) or not isinstance(current, (int, float)):
        raise ConfigError(where, f"not a numeric field (it is {type(current).__name__}); fit a number")
    if isinstance(current, int):
        raise ConfigError(where, "an integer field cannot be fitted by least squares")
    initial = float(current)
    if bounds:
        try:
            lo_s, hi_s = bounds.split(":")
            low, high = float(lo_s), float(hi_s)
        except ValueError:
            raise ConfigError(where, f"bounds must be LOW:HIGH numbers (got {bounds!r})") from None
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise ConfigError(where, f"bounds must be finite with LOW < HIGH (got {bounds!r})")
    elif initial > 0:
        low, high = initial / 10.0, initial * 10.0
    elif initial < 0:
        low, high = initial * 10.0, initial / 10.0
    else:
        raise ConfigError(where, "the current value is 0: give bounds as PATH=LOW:HIGH")
    if not low <= initial <= high:
        raise ConfigError(where, f"the starting value {initial:g} lies outside the bounds [{low:g}, {high:g}]")
    for b in (low, high):  # both bounds must be values the configuration accepts
        _with(config, path, b, f"--fit {path}: bound {b:g}")
    return FitParameter(path, initial, low, high)


def _with(config: ScenarioConfig, path: str, value: float, where: str) -> ScenarioConfig:
    try:
        return replace_path(config, path, float(value))
    except ConfigError as exc:
        raise ConfigError(where, f"out of range ({exc.field}: {exc.message})") from None


def configure(config: ScenarioConfig, params: list[FitParameter], values: Array) -> ScenarioConfig:
    for p, v in zip(params, values):
        config = _with(config, p.path, float(v), f"{p.path} = {v:g}")
    return config


def residuals(pred: Prediction, rec: Recording, orientation_weight: float = 1.0) -> Array:
    """Position errors (mm) and orientation errors (deg·weight) at the measured rows, flat."""
    err = position_errors(pred, rec) * 1000.0
    parts = [err.ravel()]
    if rec.quaternion is not None and orientation_weight > 0:
        rows = rec.measured
        qp, qm = pred.quaternion[rows], rec.quaternion[rows]
        # rotation vector of qm⁻¹·qp, small-angle: 2·vec(qm* ⊗ qp) (sign-aligned)
        w = np.sum(qp * qm, axis=1)
        s = np.sign(w + 1e-300)[:, None]
        vec = (qm[:, :1] * qp[:, 1:] - qp[:, :1] * qm[:, 1:] - np.cross(qm[:, 1:], qp[:, 1:])) * s
        parts.append(np.degrees(2.0 * vec).ravel() * orientation_weight)
    r = np.concatenate(parts)
    return np.where(np.isfinite(r), r, 1e4)  # a diverged replay: large, finite residuals


@dataclass
class FitResult:
    params: list[FitParameter]
    values: Array
    report: dict[str, Any]
    config: ScenarioConfig
    before: Prediction
    after: Prediction


def identify(config: ScenarioConfig, rec: Recording, params: list[FitParameter], nthread: int = 1,
             orientation_weight: float = 1.0, max_nfev: int = 30, progress: bool = False,
             diff_step: float = 1e-3, stride: int = 1, starts: int = 1, seed: int = 0,
             move_tol: float = 1e-6) -> FitResult:
    """Fit ``params`` to ``rec``; returns the values, the report dict and the fitted config.

    ``stride`` > 1 fits on every stride-th row only (a cheaper search on long quasi-static
    recordings, like upstream's search stride); before/after figures use every row.
    ``starts`` > 1: a multi-start, the initial values plus ``starts``−1 scrambled Sobol
    points inside the bounds (``scipy.stats.qmc``, ``seed``); the best end point is kept.
    Marker-offset parameters (``arm.tools.marker_offset.*``) move only the compared point,
    so replays are shared between values that differ only there.
    """
    from scipy.optimize import least_squares
    from scipy.stats import qmc

    start = time.process_time()
    full = rec
    if stride > 1:
        rec = rec.subset(np.arange(0, len(rec.time), stride))
    x_scale = np.array([p.scale for p in params])
    v0 = np.array([p.initial for p in params])
    lo = (np.array([p.low for p in params]) - v0) / x_scale
    hi = (np.array([p.high for p in params]) - v0) / x_scale
    marker = np.array([p.path.startswith(MARKER) for p in params])
    cache: dict[bytes, Prediction] = {}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=starts * max_nfev * (len(params) + 1), desc="identify (replays)", unit="replay", leave=False)
    count = [0]

    def run(xs: list[Array]) -> list[Array]:
        keys = [np.where(marker, 0.0, x).tobytes() for x in xs]
        todo = {k: x for k, x in zip(keys, xs) if k not in cache}
        if todo:
            cfgs = [configure(config, params, v0 + x * x_scale) for x in todo.values()]
            for k, p in zip(todo, simulate(cfgs, rec, nthread=nthread, marker=False)):
                cache[k] = p
            count[0] += len(todo)
            if bar is not None:
                bar.update(len(todo))
        out = []
        for k, x in zip(keys, xs):
            offset = configure(config, params, v0 + x * x_scale).arm.tools.marker_offset
            out.append(residuals(marker_point(cache[k], offset), rec, orientation_weight))
        return out

    def fun(x: Array) -> Array:
        return run([np.asarray(x, dtype=float)])[0]

    def jac(x: Array) -> Array:
        x = np.asarray(x, dtype=float)
        f0 = fun(x)
        steps = []
        for i in range(len(x)):
            h = diff_step * max(1.0, abs(x[i]))
            xi = x.copy()
            xi[i] = x[i] + h if x[i] + h <= hi[i] else x[i] - h
            steps.append(xi)
        cols = run(steps)
        return np.stack([(c - f0) / (s[i] - x[i]) for i, (c, s) in enumerate(zip(cols, steps))], axis=1)

    x0 = np.zeros(len(params))
    points = [x0]
    if starts > 1:
        sobol = qmc.Sobol(len(params), scramble=True, seed=seed).random(starts - 1)
        points += [lo + u * (hi - lo) for u in sobol]
    r0 = fun(x0)
    runs = []
    for p0 in points:
        sol = least_squares(fun, p0, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0, max_nfev=max_nfev,
                            xtol=1e-8, ftol=1e-10, gtol=1e-10)
        runs.append(sol)
    if bar is not None:
        bar.close()
    best = min(runs, key=lambda r: float(r.cost))
    sol = best
    values = v0 + sol.x * x_scale
    fitted = configure(config, params, values)
    J = jac(sol.x) / x_scale[None, :]  # d residual / d value, on the fitted rows
    r1 = fun(sol.x)
    report = _report(params, v0, values, r0, r1, J, rec)
    before, after = simulate([config, fitted], full, nthread=nthread)
    report["replay_before"], report["replay_after"] = replay_metrics(before, full), replay_metrics(after, full)
    report["rmse_before_mm"] = report["replay_before"]["position_error_mm"]["rms"]
    report["rmse_after_mm"] = report["replay_after"]["position_error_mm"]["rms"]
    report["stride"] = stride
    report["samples"] = int(full.measured.sum())
    report.update({"nfev": int(sol.nfev), "replays": count[0], "status": sol.message, "optimizer_status": int(sol.status),
                   "cpu_s": time.process_time() - start, "orientation_weight_mm_per_deg": orientation_weight})
    if starts > 1:
        report["multi_start"] = {"starts": starts, "seed": seed, "method": "initial values + scrambled Sobol (scipy.stats.qmc)",
                                 "runs": [{"start": (v0 + p * x_scale).tolist(), "end": (v0 + r.x * x_scale).tolist(),
                                           "cost": float(r.cost), "nfev": int(r.nfev), "status": int(r.status)}
                                          for p, r in zip(points, runs)]}
    report["warnings"] = fit_warnings(report, params, v0, values, sol.status, max_nfev, move_tol)
    return FitResult(params, values, report, fitted, before, after)


def fit_warnings(report: dict[str, Any], params: list[FitParameter], v0: Array, values: Array, status: int,
                 max_nfev: int, move_tol: float) -> list[str]:
    """What makes a fit not to be trusted as it stands: bounds, no movement, the evaluation limit."""
    out = []
    for p, d in zip(params, report["details"].values()):
        if p.initial in (p.low, p.high):
            out.append(f"{p.path} started on its bound ({p.initial:.6g} in [{p.low:.6g}, {p.high:.6g}]): "
                       "a start inside the bounds (or --starts N) tests the fit properly")
        if d["at_bound"]:
            out.append(f"{p.path} ended at its bound ({d['value']:.6g} in [{p.low:.6g}, {p.high:.6g}]): widen the bounds or fix it")
        if not d["identifiable"]:
            out.append(f"{p.path} is not identifiable: {d['why_not']}")
    moved = np.abs(values - v0) / np.array([p.high - p.low for p in params])
    before, after = report["fitted_rows_rmse_mm"]["before"], report["fitted_rows_rmse_mm"]["after"]
    if np.all(moved < move_tol) or abs(before - after) <= 1e-9 * max(before, 1e-12):
        out.append(f"the fit changed nothing (largest move {float(moved.max()):.2g} of a bound width, "
                   f"RMSE {before:.6g} -> {after:.6g} mm)")
    if status == 0:
        out.append(f"the optimiser stopped on its evaluation limit (--max-nfev {max_nfev}) before converging")
    return out


def _report(params: list[FitParameter], v0: Array, values: Array, r0: Array, r1: Array, J: Array,
            rec: Recording) -> dict[str, Any]:
    """Per-parameter uncertainty and identifiability from the Jacobian at the optimum.

    95 % half-widths: ``mujoco.sysid.calculate_intervals`` (s² = RSS/(m − n), (JᵀJ)⁻¹ by
    its eigen-decomposition, Student t). Not identifiable: a direction of JᵀJ with
    relative singular value < 1e-8 that the parameter takes part in, a step of a tenth of
    its bound width moving the residuals by < 1e-3 mm RMS (the data cannot move it), a
    95 % interval wider than its value, or a correlation above 0.999 with another.
    """
    import importlib

    # imported by name: mujoco/sysid ships a py.typed marker, and mypy following it would
    # take the whole (stub-less) mujoco package for typed and reject its C attributes
    mj_sysid = importlib.import_module("mujoco.sysid")

    m, n = J.shape
    dof = max(1, m - n)
    s2 = float(r1 @ r1) / dof
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    Jn = J / scale
    _, sv, vt = np.linalg.svd(Jn, full_matrices=False)
    rel = sv / sv[0] if sv.size and sv[0] > 0 else np.zeros_like(sv)
    weak = rel < 1e-8
    weak_dirs = vt[weak]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # on column-normalised J (parameters in units of their column norm: JᵀJ well
        # conditioned whatever the parameters' units), then back to the parameters' units
        cov_n, half_n = mj_sysid.calculate_intervals([r1], Jn)
        cov = cov_n / np.outer(scale, scale)
        half = np.asarray(half_n, dtype=float) / scale
        std = np.sqrt(np.abs(np.diag(cov)))
        corr = cov / np.outer(std, std)
    width = np.array([p.high - p.low for p in params])
    effect = np.linalg.norm(J, axis=0) * 0.1 * width / math.sqrt(max(1, m))  # RMS residual change, mm
    per: dict[str, Any] = {}
    for i, p in enumerate(params):
        reasons = []
        if effect[i] < 1e-3:
            reasons.append(f"the data cannot move it (a tenth of its bound width changes the residuals by {effect[i]:.2g} mm RMS)")
        elif weak_dirs.size and np.max(np.abs(weak_dirs[:, i])) > 0.1:
            reasons.append("the data do not change with it (rank-deficient Jacobian)")
        if not np.isfinite(half[i]) or half[i] > abs(values[i]):
            reasons.append("its 95 % interval is wider than its value")
        others = [params[j].path for j in range(n) if j != i and np.isfinite(corr[i, j]) and abs(corr[i, j]) > 0.999]
        if others:
            reasons.append(f"correlated above 0.999 with {', '.join(others)}")
        tol = 1e-6 * (p.high - p.low)
        at_bound = bool(values[i] <= p.low + tol or values[i] >= p.high - tol)
        per[p.path] = {
            "initial": float(v0[i]), "value": float(values[i]), "std_error": float(std[i]),
            "ci95": [float(values[i] - half[i]), float(values[i] + half[i])],
            "bounds": [p.low, p.high], "at_bound": at_bound, "sensitivity_mm": float(effect[i]),
            "identifiable": not reasons, "why_not": "; ".join(reasons),
        }
    npos = 3 * int(rec.measured.sum())

    def rmse(r: Array) -> float:
        e = r[:npos].reshape(-1, 3)
        return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))

    return {
        "parameters": {p.path: float(v) for p, v in zip(params, values)},
        "initial": {p.path: float(v) for p, v in zip(params, v0)},
        "rmse_before_mm": rmse(r0),
        "rmse_after_mm": rmse(r1),
        "fitted_rows_rmse_mm": {"before": rmse(r0), "after": rmse(r1)},
        "metric": "pointwise Euclidean position RMSE" + (" after removing the mean offset" if rec.info.align == "offset" else ""),
        "details": per,
        "correlation": {p.path: [float(c) for c in corr[i]] for i, p in enumerate(params)},
        "singular_values": [float(v) for v in sv], "singular_values_relative": [float(v) for v in rel],
        "uncertainty": "mujoco.sysid.calculate_intervals (95 %, s^2 = RSS/(m - n))",
        "residual_sigma": math.sqrt(s2),
        "unidentifiable": [p for p, d in per.items() if not d["identifiable"]],
    }


def identified_overrides(result: FitResult, base: dict[str, Any] | None) -> dict[str, Any]:
    """The base file's tables with the fitted values set: a file over the shipped defaults.

    A path through a list (``arm.sections.1.…``) writes that whole list, as TOML arrays of
    tables replace whole.
    """
    import copy

    out: dict[str, Any] = copy.deepcopy(base) if base else {}
    full = to_dict(result.config)
    for path in [p.path for p in result.params] + list(result.report.get("calibrated_paths", [])):
        parts = path.split(".")
        node, src = out, full
        for i, part in enumerate(parts):
            nxt = src[int(part)] if isinstance(src, list) else src[part]
            if i == len(parts) - 1:
                node[part] = nxt
            elif isinstance(nxt, list):
                node[part] = nxt
                break
            else:
                node = node.setdefault(part, {})
                src = nxt
    return out


def write_identify_folder(out: str | os.PathLike[str], result: FitResult, rec: Recording, base_toml: str | None) -> None:
    """DIR/identified.toml, DIR/report.json, DIR/plots/{fit_paths,residuals}.png."""
    from ..configio import load_toml

    out = Path(out)
    (out / "plots").mkdir(parents=True, exist_ok=True)
    lines = ["# Identified by `continuum-sim identify`: the starting configuration with the fitted values",
             "# (fitted to the recording below; report.json has their standard errors). Use it with --config.",
             f"# recording: {rec.info.source or '(unnamed)'}; {int(rec.measured.sum())} measured samples",
             *(f"# fitted {p}: {v!r}" for p, v in result.report["parameters"].items()),
             f"# starting configuration: {base_toml or 'shipped defaults'}", ""]
    base = load_toml(base_toml) if base_toml else None
    atomic_write_text(out / "identified.toml", "\n".join(lines) + dumps_toml(identified_overrides(result, base)))
    atomic_write_text(out / "report.json", json.dumps(result.report, indent=2))
    r = result.report
    plot_paths(rec, {"before fit": result.before, "after fit": result.after}, out / "plots" / "fit_paths.png",
               f"fit: RMSE {r['rmse_before_mm']:.3g} -> {r['rmse_after_mm']:.3g} mm")
    _plot_residuals(rec, result, out / "plots" / "residuals.png")


def _plot_residuals(rec: Recording, result: FitResult, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..configio import atomic_write_figure

    rows = rec.measured
    t = rec.time[rows] - rec.time[0]
    e = position_errors(result.after, rec) * 1000.0
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.5))
    for j, c in enumerate("xyz"):
        axes[0].plot(t, e[:, j], lw=0.7, label=c)
    axes[0].set_ylabel("residual after fit [mm]")
    axes[0].set_xlabel("time [s]")
    axes[0].legend(fontsize=8)
    axes[0].grid(alpha=0.3)
    axes[1].hist(e.ravel(), bins=60, color="tab:blue")
    axes[1].set_xlabel("position residual per axis [mm]")
    axes[1].set_ylabel("count")
    fig.suptitle(f"residuals after fit (sigma {np.std(e):.3g} mm per axis)")
    atomic_write_figure(fig, path)


def default_fit_max_nfev(n_params: int) -> int:
    return 20 + 5 * n_params



