"""Compare a run's metrics with a stored reference: outcome fields exactly, continuous ones within a tolerance.

Why a tolerance at all: the physics kernels are compiled by numba for the host CPU (vector
width, fused multiply-add) and MuJoCo, numpy and scipy call OpenBLAS kernels chosen for the
host CPU. Each choice rounds differently in the last bits, and over a 51 s contact-rich run
those last bits grow into visible differences (docs/architecture.md, "Results across
machines", with the study ``scripts/drift_study.py`` that measured them). On one machine a
run stays bit-identical (tests/test_scenario.py checks that); across machines the stored
reference holds within the per-metric tolerances of ``tests/data/reference_tolerance.json``.

A metrics dictionary is flattened into leaves named by their path
(``cutting_tip_error_mm.mean``, ``cable_friction.anchor_ratio_mean.left[3]``). Booleans,
strings, None and integers are *outcome* leaves and must match exactly; floats are
*continuous* leaves and must match within ``atol`` (the tolerance file's value for that path).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

from .metrics import WALL_CLOCK_METRICS

Leaf = bool | int | float | str | None


def flatten(metrics: Mapping[str, Any], skip: Iterable[str] = WALL_CLOCK_METRICS) -> dict[str, Leaf]:
    """Every leaf of a (JSON-like) metrics dictionary by its path; list lengths as ``path#len`` outcome leaves."""
    out: dict[str, Leaf] = {}
    skipped = set(skip)

    def walk(value: Any, path: str) -> None:
        if isinstance(value, Mapping):
            for key in sorted(value):
                if not path and key in skipped:
                    continue
                walk(value[key], f"{path}.{key}" if path else str(key))
        elif isinstance(value, list | tuple):
            out[f"{path}#len"] = len(value)
            for i, item in enumerate(value):
                walk(item, f"{path}[{i}]")
        else:
            out[path] = value

    walk(metrics, "")
    return out


def is_continuous(value: Leaf) -> bool:
    """Floats drift across machines; booleans, integers, strings and None are outcomes that must not."""
    return isinstance(value, float)


def mismatches(metrics: Mapping[str, Any], reference: Mapping[str, Any], atol: Mapping[str, float],
               default_atol: float = 0.0) -> list[str]:
    """One line per leaf of ``metrics`` that differs from ``reference`` beyond its tolerance (empty: they agree).

    ``atol`` maps a continuous leaf's path to its absolute tolerance; a path it does not name
    gets ``default_atol`` (0: exact). A float is never compared with a non-float.
    """
    got, want = flatten(metrics), flatten(reference)
    lines = [f"{path}: missing in the run" for path in sorted(set(want) - set(got))]
    lines += [f"{path}: not in the reference" for path in sorted(set(got) - set(want))]
    for path in sorted(set(got) & set(want)):
        a, b = got[path], want[path]
        if is_continuous(a) and is_continuous(b):
            assert isinstance(a, float) and isinstance(b, float)
            tol = atol.get(path, default_atol)
            if not (math.isfinite(a) and abs(a - b) <= tol):
                lines.append(f"{path}: {a!r} vs reference {b!r} (|diff| {abs(a - b):.3g} > tolerance {tol:.3g})")
        elif type(a) is not type(b) or a != b:
            lines.append(f"{path}: {a!r} vs reference {b!r} (outcome: must be equal)")
    return lines
