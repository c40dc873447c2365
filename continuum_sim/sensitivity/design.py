"""The samples of a study and their analysis, with SALib (Morris screening, Sobol' indices).

Sampling happens in each factor's sampling space (log10 of the range for a log factor),
so a Morris elementary effect is the change of a metric over the same fraction of every
parameter's (log) range: μ* is comparable across parameters. The samples are a pure
function of the spec (fixed seed), so a resumed study draws the same points and finds
their records.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .spec import OUTCOME_METRIC, SensitivitySpec

Number = int | float


def problem(spec: SensitivitySpec) -> dict[str, Any]:
    """SALib's problem dict (bounds in sampling space)."""
    return {"num_vars": len(spec.factors), "names": list(spec.paths), "bounds": [list(f.bounds) for f in spec.factors]}


def sample_matrix(spec: SensitivitySpec) -> np.ndarray:
    """The (rows, k) sample matrix in sampling space."""
    import warnings

    if spec.method == "morris":
        from SALib.sample import morris

        return np.asarray(morris.sample(problem(spec), spec.morris.trajectories, num_levels=spec.morris.levels,
                                        seed=spec.morris.seed), dtype=float)
    if spec.method == "uncertainty":
        from SALib.sample import latin

        return np.asarray(latin.sample(problem(spec), spec.uncertainty.samples, seed=spec.uncertainty.seed), dtype=float)
    from SALib.sample import sobol

    with warnings.catch_warnings():  # SALib warns about N not a power of 2 only; the spec enforces it
        warnings.simplefilter("ignore")
        return np.asarray(sobol.sample(problem(spec), spec.sobol.samples, calc_second_order=spec.sobol.second_order,
                                       seed=spec.sobol.seed), dtype=float)


def sample_params(spec: SensitivitySpec, matrix: np.ndarray) -> list[tuple[tuple[str, Number], ...]]:
    """Each row as (path, value) pairs in parameter units."""
    return [tuple((f.path, f.value(u)) for f, u in zip(spec.factors, row)) for row in matrix]


def outputs(rows: list[dict[str, Any] | None], metric: str) -> np.ndarray:
    """One metric per sample row; NaN where missing. A failed evaluation did not complete the task (0)."""
    y = np.full(len(rows), np.nan)
    for i, record in enumerate(rows):
        if record is None:
            continue
        value = (record.get("metrics") or {}).get(metric)
        if metric == OUTCOME_METRIC and (record.get("status") != "ok" or value is None):
            value = 0.0
        if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
            y[i] = float(value)
    return y


def analyze_morris(spec: SensitivitySpec, matrix: np.ndarray, y: np.ndarray) -> dict[str, Any]:
    """μ, μ*, σ and μ*'s 95 % bootstrap half-width per parameter; trajectories with a missing output are dropped."""
    from SALib.analyze import morris

    k = len(spec.factors)
    per = k + 1
    keep = [t for t in range(len(y) // per) if np.isfinite(y[t * per : (t + 1) * per]).all()]
    result: dict[str, Any] = {"trajectories_used": len(keep), "trajectories": len(y) // per}
    if len(keep) < 2:
        result["indices"] = None
        return result
    rows = np.concatenate([np.arange(t * per, (t + 1) * per) for t in keep])
    out = morris.analyze(problem(spec), matrix[rows], y[rows], num_levels=spec.morris.levels, seed=spec.morris.seed)
    result["indices"] = {
        path: {
            "mu": _num(out["mu"][i]),
            "mu_star": _num(out["mu_star"][i]),
            "sigma": _num(out["sigma"][i]),
            "mu_star_conf": _num(out["mu_star_conf"][i]),
        }
        for i, path in enumerate(spec.paths)
    }
    return result


def analyze_sobol(spec: SensitivitySpec, y: np.ndarray) -> dict[str, Any]:
    """First-order and total Sobol' indices with 95 % half-widths; missing outputs take the mean of the rest."""
    import warnings

    from SALib.analyze import sobol

    finite = np.isfinite(y)
    result: dict[str, Any] = {"imputed": int((~finite).sum()), "rows": len(y)}
    if finite.sum() < 2 or float(np.nanvar(y)) == 0.0:
        result["indices"] = None
        return result
    filled = np.where(finite, y, float(np.nanmean(y)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = sobol.analyze(problem(spec), filled, calc_second_order=spec.sobol.second_order, seed=spec.sobol.seed)
    result["indices"] = {
        path: {"S1": _num(out["S1"][i]), "S1_conf": _num(out["S1_conf"][i]), "ST": _num(out["ST"][i]),
               "ST_conf": _num(out["ST_conf"][i])}
        for i, path in enumerate(spec.paths)
    }
    return result


def strength(spec: SensitivitySpec, analyses: dict[str, dict[str, Any]]) -> dict[str, float]:
    """Each parameter's importance over all metrics: its μ* (Morris) or S_T (Sobol') as a share of the
    metric's largest, averaged over the metrics that could be analysed."""
    key = "mu_star" if spec.method == "morris" else "ST"
    totals = dict.fromkeys(spec.paths, 0.0)
    used = 0
    for analysis in analyses.values():
        indices = analysis.get("indices")
        if not indices:
            continue
        values = {p: max(0.0, indices[p][key] or 0.0) for p in spec.paths}
        top = max(values.values())
        if top <= 0.0:
            continue
        used += 1
        for p, v in values.items():
            totals[p] += v / top
    return {p: (v / used if used else 0.0) for p, v in totals.items()}


def _num(value: Any) -> float | None:
    v = float(value)
    return v if math.isfinite(v) else None


MORRIS_MIN_TRAJECTORIES = 10  # r below this: μ*'s bootstrap intervals are unstable (SALib's examples use r >= 10)
SOBOL_MIN_SAMPLES = 64  # N below this: the bootstrap intervals of S1 and S_T are not to be trusted
SOBOL_MIN_INDEX = 0.05  # an index this large whose interval reaches past zero is not resolved


def _next_power_of_2(n: float) -> int:
    return 1 << max(0, math.ceil(math.log2(max(n, 1.0))))


def sample_size_warnings(spec: SensitivitySpec, analyses: dict[str, dict[str, Any]]) -> list[str]:
    """Where the sample is too small for its confidence intervals, and the size that would do.

    Morris: r < 10 trajectories (or fewer than that left once failed evaluations are dropped).
    Sobol': N < 64, or an index that matters (≥ 0.05) with a 95 % half-width larger than itself;
    half-widths shrink as 1/√N, so the size that brings it to half the index is named.
    """
    k = len(spec.factors)
    out: list[str] = []
    if spec.method == "morris":
        r = spec.morris.trajectories
        if r < MORRIS_MIN_TRAJECTORIES:
            out.append(f"Morris r = {r} trajectories is too few for μ*'s 95 % intervals; r = {MORRIS_MIN_TRAJECTORIES} would do "
                       f"({MORRIS_MIN_TRAJECTORIES * (k + 1)} runs for {k} parameters)")
        for metric, analysis in analyses.items():
            used = analysis.get("trajectories_used")
            if used is not None and used < min(r, MORRIS_MIN_TRAJECTORIES):
                out.append(f"{metric}: only {used} of {r} trajectories have every evaluation (failed ones are dropped); "
                           f"its intervals rest on {used}")
    elif spec.method == "sobol":
        n = spec.sobol.samples
        per = 2 * k + 2 if spec.sobol.second_order else k + 2
        if n < SOBOL_MIN_SAMPLES:
            out.append(f"Sobol' N = {n} is too small for the indices' 95 % intervals; N = {SOBOL_MIN_SAMPLES} would do "
                       f"({SOBOL_MIN_SAMPLES * per} runs for {k} parameters)")
        for metric, analysis in analyses.items():
            worst: tuple[float, str, str, float, float] | None = None
            for path, v in (analysis.get("indices") or {}).items():
                for name in ("ST", "S1"):
                    index, conf = v.get(name), v.get(f"{name}_conf")
                    if index is None or conf is None or index < SOBOL_MIN_INDEX or conf <= index:
                        continue
                    ratio = conf / index
                    if worst is None or ratio > worst[0]:
                        worst = (ratio, path, name, index, conf)
            if worst is not None:
                ratio, path, name, index, conf = worst
                need = min(1 << 16, max(_next_power_of_2(n * (2.0 * ratio) ** 2), SOBOL_MIN_SAMPLES))
                out.append(f"{metric}: {name} of {path} is {index:.3g} ± {conf:.3g}, a 95 % half-width larger than the index; "
                           f"N = {need} would bring it to about half ({need * per} runs)")
    return out
