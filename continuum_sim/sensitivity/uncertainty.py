"""Uncertainty propagation: how likely the task succeeds when the assumed parameters are anywhere in their ranges.

Where Morris and Sobol' rank parameters, this method answers the user's question directly:
a Latin hypercube sample (SALib) of the parameters over their ranges, each sample run through
the evaluation, and the fraction that *succeed* (the task completes and every metric of the
spec's ``[success]`` table is within its bounds) with its exact 95 % Clopper–Pearson interval
(scipy). Beside it: why the others failed (the task's failure name, or the metric outside its
bound), each parameter's success rate in the lower and the upper half of its range, and
where the base configuration's own values sit in each range.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np

from ..params.registry import parameter
from .spec import SensitivitySpec
from .success import COMPLETED, FAILURE, Bound


def verdict(record: dict[str, Any] | None, success: tuple[Bound, ...]) -> tuple[bool | None, str]:
    """(succeeded, why not) of one sample; (None, 'pending') before it ran."""
    if record is None:
        return None, "pending"
    if record.get("status") != "ok":
        return False, f"evaluation failed: {str(record.get('error') or record.get('status'))[:60]}"
    metrics = record.get("metrics") or {}
    if not metrics.get(COMPLETED):
        return False, str(metrics.get(FAILURE) or "not completed")
    for bound in success:
        if not bound.holds(metrics.get(bound.metric)):
            return False, f"completed, but not {bound.text()}"
    return True, "success"


def clopper_pearson(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """The exact binomial interval of k successes in n trials."""
    from scipy.stats import binomtest

    ci = binomtest(k, n).proportion_ci(confidence_level=confidence, method="exact")
    return float(ci.low), float(ci.high)


def analyze(spec: SensitivitySpec, values: np.ndarray, rows: list[dict[str, Any] | None]) -> dict[str, Any]:
    """Success probability with its interval, failure modes, success by half range, the base's place."""
    verdicts = [verdict(r, spec.success) for r in rows]
    done = [(i, ok, why) for i, (ok, why) in enumerate(verdicts) if ok is not None]
    n = len(done)
    k = sum(1 for _, ok, _ in done if ok)
    completed = sum(1 for i, _, _ in done if ((rows[i] or {}).get("metrics") or {}).get(COMPLETED))
    result: dict[str, Any] = {
        "criterion": ["task completed", *[b.text() for b in spec.success]],
        "samples": len(rows),
        "recorded": n,
        "successes": k,
        "completed": completed,
        "probability": k / n if n else None,
        "interval_95": list(clopper_pearson(k, n)) if n else None,
        "completed_probability": completed / n if n else None,
        "completed_interval_95": list(clopper_pearson(completed, n)) if n else None,
        "failures": dict(Counter(why for _, ok, why in done if not ok).most_common()),
    }
    by_half = {}
    position = {}
    for j, factor in enumerate(spec.factors):
        lo, hi = factor.bounds
        u = np.log10(values[:, j]) if factor.log else values[:, j]
        middle = 0.5 * (lo + hi)
        halves = {}
        for name, mask in (("lower", u < middle), ("upper", u >= middle)):
            picked = [ok for i, ok, _ in done if mask[i]]
            halves[name] = {"n": len(picked), "success": (sum(picked) / len(picked)) if picked else None}
        by_half[factor.path] = halves
        base = parameter(factor.path).value(spec.base)
        ub = math.log10(base) if factor.log and base > 0 else base
        position[factor.path] = {"value": base, "fraction_of_range": (ub - lo) / (hi - lo)}
    result["success_by_half_range"] = by_half
    result["base_position"] = position
    return result


def strength(spec: SensitivitySpec, analysis: dict[str, Any]) -> dict[str, float]:
    """Each parameter's effect on success: |success rate in the upper half - in the lower half| of its range."""
    out = {}
    for path in spec.paths:
        halves = analysis["success_by_half_range"][path]
        lo, hi = halves["lower"]["success"], halves["upper"]["success"]
        out[path] = abs(hi - lo) if lo is not None and hi is not None else 0.0
    return out


def markdown(summary: dict[str, Any]) -> str:
    """The result as the markdown the docs quote."""
    a = summary["analysis"]["uncertainty"]

    def pct(v: float | None) -> str:
        return "–" if v is None else f"{100 * v:.0f} %"

    lines = [
        f"uncertainty study, {summary['control_mode']} loop, {summary['evaluation']['kind']}: "
        f"{a['recorded']}/{a['samples']} Latin hypercube samples over {len(summary['parameters'])} parameters, "
        f"{summary['cpu_s_total']:.0f} s CPU.",
        "",
        f"Success ({' and '.join(a['criterion'])}): **{a['successes']} of {a['recorded']} = {pct(a['probability'])}**, "
        + ("95 % interval " + " – ".join(pct(v) for v in a["interval_95"]) if a["interval_95"] else "no interval")
        + f"; task completed in {a['completed']} of {a['recorded']}"
        + (f" ({' – '.join(pct(v) for v in a['completed_interval_95'])})." if a["completed_interval_95"] else "."),
        "",
        "| outcome | samples |",
        "|---|---|",
        *[f"| {why} | {count} |" for why, count in sorted(a["failures"].items(), key=lambda kv: -kv[1])],
        f"| success | {a['successes']} |",
        "",
        "| parameter | range | base value (place in range) | success, lower half | success, upper half |",
        "|---|---|---|---|---|",
    ]
    for p in summary["parameters"]:
        path = p["path"]
        halves = a["success_by_half_range"][path]
        base = a["base_position"][path]
        low, high = p["range"]
        lines.append(
            f"| `{path}` | {low:g} – {high:g}{' log' if p['log'] else ''} | {base['value']:.4g} ({pct(base['fraction_of_range'])}) "
            f"| {pct(halves['lower']['success'])} of {halves['lower']['n']} | {pct(halves['upper']['success'])} of {halves['upper']['n']} |"
        )
    return "\n".join(lines) + "\n"
