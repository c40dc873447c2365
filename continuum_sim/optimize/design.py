"""From a study's trials to sweep variants: design values, robustness samples, configurations.

Every evaluation is a sweep ``Variant`` (``params`` = the design's values, then the
sample's assumed-parameter values; ``variant_id`` = a hash of them and the evaluation), so
the sweep's store records each one once and an evaluation that already has a record is
never run again, whichever trial asks for it.

Robustness uses common random numbers: the same ``samples`` draws of the assumed
parameters (a Latin hypercube over their ranges, log10 space where the registry samples
logarithmically, seeded by the optimiser's seed) for every design, so two designs are
compared on the same plants.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any

from ..configio import ConfigError, from_dict, set_path, to_dict
from ..sweep.spec import SweepSpec, Variant, variant_id
from .spec import OptimizeSpec, Variable

Params = tuple[tuple[str, float | int], ...]


@dataclass(frozen=True)
class StudySweep(SweepSpec):
    """The study as the sweep store and backends see it; its identity is the whole optimisation spec."""

    study: dict[str, Any] = field(default_factory=dict)

    def identity(self) -> dict[str, Any]:
        return {"base": to_dict(self.base), "grid": self.study, "evaluation": self.evaluation.to_dict()}


def study_sweep(spec: OptimizeSpec) -> StudySweep:
    identity = spec.identity()
    identity.pop("base")
    identity.pop("evaluation")
    return StudySweep(spec.base, (), spec.evaluation, (), spec.base_path, spec.source_text, study=identity)


def robustness_samples(spec: OptimizeSpec) -> list[Params]:
    """The assumed-parameter values of each robustness sample (one empty sample without robustness)."""
    rob = spec.robustness
    if not rob.samples:
        return [()]
    from scipy.stats import qmc

    unit = qmc.LatinHypercube(d=len(rob.parameters), seed=spec.optimizer.seed).random(rob.samples)
    out: list[Params] = []
    for row in unit:
        values = []
        for u, p in zip(row, rob.parameters):
            if p.log:
                v = 10.0 ** (math.log10(p.low) + u * (math.log10(p.high) - math.log10(p.low)))
            else:
                v = p.low + u * (p.high - p.low)
            values.append((p.path, float(f"{min(max(v, p.low), p.high):.12g}")))  # 12 digits: stable ids
        out.append(tuple(values))
    return out


def design_params(spec: OptimizeSpec, values: dict[str, Any]) -> Params:
    """A trial's design values in variable order, of each field's type."""
    return tuple((v.path, int(values[v.path]) if v.integer else float(values[v.path])) for v in spec.variables)


def evaluation_variant(spec: OptimizeSpec, design: Params, sample: Params, index: int) -> Variant:
    params = design + sample
    return Variant(index, params, variant_id(params, spec.evaluation))


def config_dict(spec: OptimizeSpec, params: Params) -> dict[str, Any]:
    """The base configuration (as a dict) with ``params`` set."""
    data = copy.deepcopy(to_dict(spec.base))
    for path, value in params:
        set_path(data, path, value)
    return data


def check_config(spec: OptimizeSpec, params: Params) -> Any:
    """The configuration of ``params``, validated as a sweep validates a variant; ``ConfigError`` naming the field."""
    from ..limits import check_model_geometry, check_scenario

    config = from_dict(type(spec.base), config_dict(spec, params))
    if spec.evaluation.static:
        check_model_geometry(config)
    else:
        check_scenario(config)
    spec.evaluation.check(config)
    return config


def _corner(variables: tuple[Variable, ...], pick: int) -> Params:
    return tuple((v.path, (int(v.low) if v.integer else v.low) if pick == 0 else (int(v.high) if v.integer else v.high)) for v in variables)


def check_designs(spec: OptimizeSpec) -> None:
    """Before any work: each variable's bounds alone, the all-low and all-high corners, and every robustness sample.

    The design space is continuous, so this cannot check every design: a design that still
    turns out invalid is recorded as a failed trial naming the field, and the study goes on.
    """
    candidates: list[tuple[str, Params]] = []
    for v in spec.variables:
        for bound in ("low", "high"):
            value = getattr(v, bound)
            candidates.append((f"variables.{v.path}.{bound}", ((v.path, int(value) if v.integer else value),)))
    candidates += [("variables", _corner(spec.variables, 0)), ("variables", _corner(spec.variables, 1))]
    for i, sample in enumerate(robustness_samples(spec)):
        if sample:
            candidates.append((f"robustness (sample {i})", sample))
    for where, params in candidates:
        try:
            check_config(spec, params)
        except ConfigError as exc:
            label = ", ".join(f"{p} = {v:g}" for p, v in params)
            raise ConfigError(where, f"{exc.field}: {exc.message} (at {label}); narrow the range") from None
