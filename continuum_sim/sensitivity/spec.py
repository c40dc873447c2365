"""Sensitivity study spec: which registry parameters, over which ranges, evaluated how, analysed how.

A spec is a TOML file::

    base = "my_scenario.toml"          # optional, relative to the spec file
    method = "morris"                  # morris (screening) | sobol (variance shares) | uncertainty (success probability)
    parameters = ["model.cable_friction.mu", "scene.tools.gripper_preload"]   # registry paths
    metrics = ["task.completed", "cut_path_deviation_mm.mean"]               # optional

    [ranges]                           # optional: narrower/other ranges than the registry's
    "model.cable_friction.mu" = [0.0, 0.2]

    [config.control]                   # optional: settings over the base (a scenario TOML's tables)
    mode = "open"

    [morris]                           # trajectories r, grid levels p, seed
    trajectories = 4
    levels = 4
    seed = 0

    [sobol]                            # base samples N (a power of 2), second-order indices
    samples = 64
    second_order = false
    seed = 0

    [uncertainty]                      # Latin hypercube points, seed (uncertainty.py)
    samples = 64
    seed = 0

    [success]                          # uncertainty: what counts as success besides the task completing
    "cut_path_deviation_mm.mean" = {max = 2.5}

    [evaluation]                       # as in a sweep spec: scenario | stage | gravity_sag | tip_deflection
    kind = "scenario"

Ranges default to the parameter registry's plausible ranges (``continuum_sim.params``);
a parameter the registry samples logarithmically is sampled in log10 space. Everything is
checked before any simulation: paths, ranges, sample counts, the evaluation, and every
sample's configuration. Errors are one-line ``ConfigError``s naming the field.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..configio import ConfigError, get_path, parse_toml_text, read_config_text, require_int, to_dict
from ..params.registry import parameter
from ..scenario.config import ScenarioConfig
from ..sweep.evaluations import Evaluation, parse_evaluation
from ..sweep.spec import check_keys, spec_base
from .success import COMPLETED, FAILURE, Bound, UncertaintyOptions, parse_success

METHODS = ("morris", "sobol", "uncertainty")
# The task outcome and the metrics the issue names (metrics.json, flattened with dots).
DEFAULT_METRICS = (
    "task.completed",  # 1 = the task completed, 0 = not (a failed evaluation counts as 0)
    "cut_path_deviation_mm.mean",  # path deviation on the plate (the paper's 2.5 mm)
    "cutting_tip_error_mm.mean",  # cutting error of the grinder
    "tip_error_mm.right.clamping.max",  # clamping-stage error of the gripper arm
    "max_cable_tension_n",  # peak cable tension
)
OUTCOME_METRIC = "task.completed"
MAX_EVALUATIONS = 20_000


@dataclass(frozen=True)
class Factor:
    """One sampled parameter: registry path, range, log10 sampling."""

    path: str
    low: float
    high: float
    log: bool
    integer: bool = False  # the config field is an integer (a segment count): samples round to it

    @property
    def bounds(self) -> tuple[float, float]:
        """The bounds in sampling space (log10 of the range for a log factor)."""
        return (math.log10(self.low), math.log10(self.high)) if self.log else (self.low, self.high)

    def value(self, u: float) -> float | int:
        """A sampling-space coordinate as the parameter's value (12 significant digits: stable ids)."""
        v = min(max(10.0**u if self.log else u, self.low), self.high)
        return int(round(v)) if self.integer else float(f"{v:.12g}")


@dataclass(frozen=True)
class MorrisOptions:
    trajectories: int = 4  # r: elementary effects per parameter
    levels: int = 4  # p: grid levels of each parameter's range
    seed: int = 0

    def __post_init__(self) -> None:
        require_int("morris.trajectories", self.trajectories, 2, 1000)
        require_int("morris.levels", self.levels, 2, 100)
        if self.levels % 2:
            raise ConfigError("morris.levels", f"must be even (Morris' Δ = p/(2(p-1)) needs an even p; got {self.levels})")
        require_int("morris.seed", self.seed, 0)


@dataclass(frozen=True)
class SobolOptions:
    samples: int = 64  # N: base samples; N·(k+2) evaluations (N·(2k+2) with second order)
    second_order: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        require_int("sobol.samples", self.samples, 2, 1 << 16)
        if self.samples & (self.samples - 1):
            raise ConfigError("sobol.samples", f"must be a power of 2 (Sobol' sequence balance; got {self.samples})")
        require_int("sobol.seed", self.seed, 0)


@dataclass(frozen=True)
class SensitivitySpec:
    """A validated study."""

    base: ScenarioConfig
    factors: tuple[Factor, ...]
    method: str
    evaluation: Evaluation
    metrics: tuple[str, ...]
    morris: MorrisOptions = field(default_factory=MorrisOptions)
    sobol: SobolOptions = field(default_factory=SobolOptions)
    base_path: str | None = None
    source_text: str = ""
    uncertainty: UncertaintyOptions = field(default_factory=UncertaintyOptions)
    success: tuple[Bound, ...] = ()

    @property
    def paths(self) -> tuple[str, ...]:
        return tuple(f.path for f in self.factors)

    def design(self) -> dict[str, Any]:
        """What fixes the samples: the study's identity beside the base config and the evaluation."""
        options = to_dict({"morris": self.morris, "sobol": self.sobol, "uncertainty": self.uncertainty}[self.method])
        design = {
            "method": self.method,
            "factors": [[f.path, f.low, f.high, f.log] for f in self.factors],
            "options": options,
            "salib": _salib_version(),
        }
        if self.method == "uncertainty":
            design["success"] = [[b.metric, b.low, b.high] for b in self.success]
        return design


def _salib_version() -> str:
    from importlib import metadata

    try:
        version = metadata.version("SALib")
    except metadata.PackageNotFoundError:
        raise ConfigError("method", "SALib is not installed; install it with pip install 'continuum_sim[sensitivity]'") from None
    return version.split(".")[0]  # the sampler's major version: a new one may draw other samples


def _factor(path: Any, ranges: dict[str, Any], where: str, base: ScenarioConfig) -> Factor:
    if not isinstance(path, str) or not path:
        raise ConfigError(where, f"must be a registry parameter path (got {path!r})")
    try:
        entry = parameter(path)
    except ConfigError as exc:
        raise ConfigError(where, f"{exc.field}: {exc.message}") from None
    raw = ranges.get(path)
    if raw is None:
        if entry.range is None:
            raise ConfigError(where, f"{path} has no plausible range in the registry ({entry.status}); give one under [ranges]")
        low, high = entry.range
    else:
        key = f"ranges.{path}"
        if not isinstance(raw, list) or len(raw) != 2:
            raise ConfigError(key, f"must be [low, high] (got {raw!r})")
        for i, v in enumerate(raw):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"{key}[{i}]", f"must be a finite number (got {v!r})")
        low, high = float(raw[0]), float(raw[1])
    if not low < high:
        raise ConfigError(f"ranges.{path}", f"must satisfy low < high (got [{low:g}, {high:g}])")
    if entry.log and low <= 0.0:
        raise ConfigError(f"ranges.{path}", f"is sampled logarithmically: low must be > 0 (got {low:g})")
    current = get_path(base, path)
    return Factor(path, float(low), float(high), entry.log, isinstance(current, int) and not isinstance(current, bool))


def parse_spec(data: dict[str, Any], spec_dir: str | os.PathLike[str] | None = None, source_text: str = "") -> SensitivitySpec:
    """Validate a spec dict (as read from TOML) into a ``SensitivitySpec``; ``ConfigError`` if bad."""
    allowed = ("base", "method", "parameters", "metrics", "ranges", "config", "morris", "sobol", "uncertainty", "success", "evaluation")
    check_keys(data, allowed)
    base, base_path = spec_base(data, spec_dir, with_settings=True)

    method = data.get("method", "morris")
    if method not in METHODS:
        raise ConfigError("method", f"must be one of {', '.join(METHODS)} (got {method!r})")
    names = data.get("parameters")
    if not isinstance(names, list) or not names:
        raise ConfigError("parameters", "must be a non-empty list of registry paths (continuum-sim params lists them)")
    ranges = data.get("ranges", {})
    if not isinstance(ranges, dict):
        raise ConfigError("ranges", f"must be a table of path = [low, high] (got {type(ranges).__name__})")
    for path in ranges:
        if path not in names:
            raise ConfigError(f"ranges.{path}", "is not among the study's parameters")
    factors = tuple(_factor(p, ranges, f"parameters[{i}]", base) for i, p in enumerate(names))
    if len({f.path for f in factors}) != len(factors):
        raise ConfigError("parameters", "a parameter is listed twice")
    if method == "sobol" and len(factors) < 2:
        raise ConfigError("parameters", "Sobol' analysis needs at least 2 parameters")

    def options(cls: type, key: str) -> Any:
        raw = data.get(key, {})
        if not isinstance(raw, dict):
            raise ConfigError(key, f"must be a table (got {type(raw).__name__})")
        from ..configio import from_dict

        return from_dict(cls, raw, prefix=key)

    morris, sobol = options(MorrisOptions, "morris"), options(SobolOptions, "sobol")
    uncertainty = options(UncertaintyOptions, "uncertainty")
    success = parse_success(data.get("success"))
    if success and method != "uncertainty":
        raise ConfigError("success", "only applies to method = \"uncertainty\"")

    evaluation = parse_evaluation(data.get("evaluation", {"kind": "scenario"}))
    metrics_raw = data.get("metrics")
    if metrics_raw is None:
        metrics = DEFAULT_METRICS if not evaluation.static else tuple(evaluation.default_metrics())
    else:
        if not isinstance(metrics_raw, list) or not metrics_raw:
            raise ConfigError("metrics", "must be a non-empty list of metric names (metrics.json keys joined with dots)")
        known = evaluation.known_metrics()
        for i, name in enumerate(metrics_raw):
            if not isinstance(name, str) or not name:
                raise ConfigError(f"metrics[{i}]", f"must be a metric name (got {name!r})")
            if known is not None and name not in known:
                raise ConfigError(f"metrics[{i}]", f"unknown metric {name!r} for {evaluation.kind}; known: {', '.join(known)}")
        if len(set(metrics_raw)) != len(metrics_raw):
            raise ConfigError("metrics", "a metric is listed twice")
        metrics = tuple(metrics_raw)
    if method == "uncertainty":
        if evaluation.static:
            raise ConfigError("evaluation.kind", "the uncertainty method needs a task evaluation (scenario or stage)")
        known = evaluation.known_metrics()
        for bound in success:
            if known is not None and bound.metric not in known:
                raise ConfigError(f"success.{bound.metric}", f"unknown metric for {evaluation.kind}; known: {', '.join(known)}")
        wanted = [COMPLETED, FAILURE, *[b.metric for b in success]]
        metrics = tuple(dict.fromkeys([*wanted, *metrics]))
    spec = SensitivitySpec(base, factors, method, evaluation, metrics, morris, sobol, base_path, source_text, uncertainty, success)
    n = n_evaluations(spec)
    if n > MAX_EVALUATIONS:
        raise ConfigError(method, f"{n} evaluations is more than the limit of {MAX_EVALUATIONS}")
    return spec


def n_evaluations(spec: SensitivitySpec) -> int:
    """Rows of the sample matrix (distinct configurations may be fewer: Morris trajectories can share points)."""
    k = len(spec.factors)
    if spec.method == "morris":
        return spec.morris.trajectories * (k + 1)
    if spec.method == "uncertainty":
        return spec.uncertainty.samples
    return spec.sobol.samples * (2 * k + 2 if spec.sobol.second_order else k + 2)


def load_spec(path: str | os.PathLike[str]) -> SensitivitySpec:
    """Read and validate a study spec TOML; errors name the file and the field."""
    path = Path(path)
    text = read_config_text(path)
    data = parse_toml_text(text, str(path))
    try:
        return parse_spec(data, path.parent, text)
    except ConfigError as exc:
        raise exc.under(f"{path}: ") from None
