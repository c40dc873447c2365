"""From a study's trials to sweep variants: design values, robustness samples, configurations.

Every evaluation is a sweep ``Variant`` (``params`` = the design's values, then the
sample's assumed-parameter values; ``variant_id`` = a hash of them and the evaluation), so
the sweep's store records each one once and an evaluation that already has a record is
never run again, whichever trial asks for it.

Robustness uses common random numbers: the same ``samples`` draws of the assumed
parameters (a Latin hypercube over their ranges, log10 space where the registry samples
logarithmically, seeded by the optimiser's seed) for every design, so two designs are
compared on the same plants.

A best design's TOML is headed by ``header_lines``: the study it came from (folder, spec
hash, provenance commit) and what reproduces its objective values (the evaluation, the
objectives and constraints, the robustness samples' values, the values recorded), which
``continuum-sim evaluate`` reads back (``read_header``, ``header_spec``).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any

from ..configio import ConfigError, from_dict, set_path, to_dict
from ..sweep.spec import SweepSpec, Variant, variant_id
from .spec import SUCCESS, OptimizeSpec, Variable

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


# ------------------------------------------------------------------ best designs: the header that reproduces them
HEADER_TITLE = "continuum-sim design"
HEADER_KEYS = ("study", "study_name", "storage", "spec_sha256", "study_sha256", "commit", "dirty", "code_sha256", "trial",
               "evaluation", "objectives", "constraints", "min_success", "samples", "values", SUCCESS)


def header_lines(spec: OptimizeSpec, *, trial: int, values: list[float], success: float | None, samples: list[Params],
                 folder: str, study: dict[str, Any], provenance: dict[str, Any]) -> list[str]:
    """The comment lines heading a best design's TOML: the study it came from and what reproduces its objectives.

    Each data line is ``key: JSON`` (floats written exactly), so ``read_header`` gives back the
    evaluation, the objectives (with their aggregation), the constraints, the robustness
    samples' values and the recorded objective values; ``continuum-sim evaluate`` needs
    nothing else. The study's folder, spec hash and provenance commit say where it came from.
    """
    import json

    git = provenance.get("git") or {}
    hashes = provenance.get("hashes") or {}
    data: dict[str, Any] = {
        "study": folder,
        "study_name": study.get("name"),
        "storage": study.get("storage"),
        "spec_sha256": hashes.get("spec"),
        "study_sha256": study.get("spec_sha256"),
        "commit": git.get("commit"),
        "dirty": git.get("dirty"),
        "code_sha256": provenance.get("code_sha256"),
        "trial": trial,
        "evaluation": spec.evaluation.to_dict(),
        "objectives": [{"label": o.label, "metric": o.metric, "direction": o.direction, "aggregate": o.aggregate, "q": o.q}
                       for o in spec.objectives],
        "constraints": [{"metric": c.metric, "min": c.low, "max": c.high} for c in spec.constraints],
        "min_success": spec.robustness.min_success,
        "samples": [[[p, v] for p, v in sample] for sample in samples],
        "values": dict(zip([o.label for o in spec.objectives], values)),
        SUCCESS: success,
    }
    lines = [f"{HEADER_TITLE}: trial {trial}, a best design of the optimisation study in {folder}",
             f"reproduce its objective values: continuum-sim evaluate {folder}/best/trial_{trial}.toml",
             "the lines below are read back by continuum-sim evaluate (key: JSON); the tables after them are the scenario"]
    return lines + [f"{key}: {json.dumps(data[key], sort_keys=True, allow_nan=False)}" for key in HEADER_KEYS]


def read_header(text: str) -> dict[str, Any] | None:
    """The ``key: JSON`` lines of a best design's header (``header_lines``); None when the file has no such header."""
    import json

    out: dict[str, Any] = {}
    for line in text.splitlines():
        if not line.startswith("#"):
            if line.strip():
                break  # the header is the comment block at the top
            continue
        key, sep, value = line[1:].strip().partition(": ")
        if sep and key in HEADER_KEYS:
            try:
                out[key] = json.loads(value)
            except json.JSONDecodeError:
                raise ConfigError(f"header.{key}", f"is not valid JSON ({value[:60]!r}); the file's header was edited") from None
    return out if "evaluation" in out else None


def header_spec(base: Any, header: dict[str, Any], evaluation: Any) -> tuple[OptimizeSpec, list[Params]]:
    """An ``OptimizeSpec`` holding what the study aggregated a design with (objectives, constraints, robustness),
    rebuilt from a best design's header over ``base``, and the robustness samples' values."""
    from .spec import Bound, Objective, Optimizer, Robustness, Uncertain

    try:
        objectives = tuple(Objective(o["metric"], o["direction"], o["aggregate"], float(o["q"])) for o in header.get("objectives", []))
        constraints = tuple(Bound(c["metric"], c.get("min"), c.get("max")) for c in header.get("constraints", []))
        samples: list[Params] = [tuple((str(p), v) for p, v in sample) for sample in header.get("samples", [])]
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError("header", f"cannot read the study's objectives, constraints or samples ({exc}); the file's header was edited") from None
    paths = tuple(dict.fromkeys(p for sample in samples for p, _ in sample))
    robustness = Robustness(len(samples), tuple(Uncertain(p, 0.0, 1.0, False) for p in paths), header.get("min_success"))
    spec = OptimizeSpec(base, (), objectives, constraints, robustness, Optimizer(), evaluation)
    return spec, samples or [()]
