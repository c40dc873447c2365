"""Design-optimisation spec: design variables, objectives, constraints, robustness, optimiser.

A spec is a TOML file::

    base = "my_scenario.toml"          # optional, relative to the spec file
    [config.control]                   # optional: settings over the base (a scenario TOML's tables)
    mode = "open"

    [variables]                        # any numeric config path: bounds, log scale, integers
    "arm.sections.0.stiffness_scale" = {low = 0.5, high = 4.0, log = true}
    "control.pretension" = {low = 15, high = 50, grid = 5}     # grid: points for sampler = "grid"
    "model.segments_per_section" = {low = 4, high = 12, int = true}

    [[objectives]]                     # task metrics (metrics.json keys joined with dots)
    metric = "cut_path_deviation_mm.mean"
    direction = "minimize"             # minimize | maximize
    aggregate = "mean"                 # robust studies: mean | quantile (with q)
    q = 0.9

    [constraints]                      # per evaluation; a robust study's success = all hold
    completed = true                   # task.completed == 1
    motors_not_saturated = true        # task.cables_saturated == 0
    min_arm_clearance_m = 0.005        # min_arm_distance_m >= x
    [constraints.metrics]              # any metric: {min = x} and/or {max = y}
    "cutting_tip_error_mm.mean" = {max = 0.15}

    [robustness]                       # optional: N samples of assumed parameters per design
    samples = 8
    parameters = ["model.cable_friction.mu", "model.rope_modulus"]   # registry paths, their ranges
    ranges = {"model.cable_friction.mu" = [0.05, 0.3]}               # optional, other ranges
    min_success = 0.8                  # constraint: success probability >= p

    [optimizer]
    sampler = "nsga2"                  # nsga2 | tpe | cmaes (one objective, no constraints) | random | grid
    trials = 60                        # designs to evaluate (evaluations = trials x samples)
    batch = 4                          # designs asked per generation (NSGA-II's population)
    seed = 0

    [evaluation]                       # as in a sweep spec (continuum_sim.sweep.evaluations)
    kind = "scenario"

``load_spec`` parses and checks the fields; ``design.check_designs`` (run by ``run_study``
before the folder is touched) checks the configurations at the design box's bounds and
every robustness sample. The objective ``success_probability`` (robust studies) is the share of a design's samples
in which every constraint holds. Everything is checked before any simulation; errors are
one-line ``ConfigError``s naming the field and what it allows.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..configio import ConfigError, get_path, migration_note, parse_toml_text, read_config_text, require_int, require_range, to_dict, unknown_path_error
from ..params.registry import parameter
from ..scenario.config import ScenarioConfig
from ..sweep.evaluations import Evaluation, parse_evaluation
from ..sweep.spec import check_keys, spec_base

SAMPLERS = ("nsga2", "tpe", "cmaes", "random", "grid")
SUCCESS = "success_probability"
COMPLETED, SATURATED, CLEARANCE = "task.completed", "task.cables_saturated", "min_arm_distance_m"
MAX_TRIALS = 10_000
MAX_SAMPLES = 256


@dataclass(frozen=True)
class Variable:
    """One design variable: a numeric config path and its search range."""

    path: str
    low: float
    high: float
    log: bool = False
    integer: bool = False
    grid: int = 0  # points for the grid sampler (0: not given)

    def grid_values(self) -> list[float | int]:
        """``grid`` points from low to high (geometric when ``log``), for the grid sampler."""
        import numpy as np

        n = self.grid
        raw = np.geomspace(self.low, self.high, n) if self.log else np.linspace(self.low, self.high, n)
        if self.integer:
            return sorted({int(round(v)) for v in raw})
        return [float(f"{v:.12g}") for v in raw]


@dataclass(frozen=True)
class Objective:
    metric: str
    direction: str = "minimize"
    aggregate: str = "mean"  # over a robust design's samples: mean | quantile
    q: float = 0.5

    @property
    def label(self) -> str:
        if self.metric == SUCCESS or self.aggregate == "mean":
            return self.metric
        return f"{self.metric}@q{self.q:g}"


@dataclass(frozen=True)
class Bound:
    """A constraint ``low <= metric <= high`` on one evaluation (None: unbounded)."""

    metric: str
    low: float | None = None
    high: float | None = None

    def holds(self, metrics: dict[str, Any]) -> bool:
        value = metrics.get(self.metric)
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            return False
        return (self.low is None or value >= self.low) and (self.high is None or value <= self.high)

    def violation(self, metrics: dict[str, Any]) -> float:
        """How far outside (0 when it holds; 1 when the metric is missing)."""
        value = metrics.get(self.metric)
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            return 1.0
        low = 0.0 if self.low is None else max(0.0, self.low - value)
        high = 0.0 if self.high is None else max(0.0, value - self.high)
        return low + high


@dataclass(frozen=True)
class Uncertain:
    """An assumed parameter sampled per design: registry path, range, log10 sampling."""

    path: str
    low: float
    high: float
    log: bool


@dataclass(frozen=True)
class Robustness:
    samples: int = 0  # 0: no robustness (one evaluation per design)
    parameters: tuple[Uncertain, ...] = ()
    min_success: float | None = None


@dataclass(frozen=True)
class Optimizer:
    sampler: str = "nsga2"
    trials: int = 60
    batch: int = 4
    seed: int = 0


@dataclass(frozen=True)
class OptimizeSpec:
    """A validated design study."""

    base: ScenarioConfig
    variables: tuple[Variable, ...]
    objectives: tuple[Objective, ...]
    constraints: tuple[Bound, ...]
    robustness: Robustness
    optimizer: Optimizer
    evaluation: Evaluation
    base_path: str | None = None
    source_text: str = ""
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        return max(1, self.robustness.samples)

    @property
    def robust(self) -> bool:
        return self.robustness.samples > 0

    @property
    def directions(self) -> list[str]:
        return [o.direction for o in self.objectives]

    def identity(self) -> dict[str, Any]:
        """What a study folder must match to be resumed."""
        return {
            "base": to_dict(self.base),
            "variables": [to_dict(v) for v in self.variables],
            "objectives": [to_dict(o) for o in self.objectives],
            "constraints": [to_dict(c) for c in self.constraints],
            "robustness": to_dict(self.robustness),
            "optimizer": to_dict(self.optimizer),
            "evaluation": self.evaluation.to_dict(),
        }


# ------------------------------------------------------------------------ parsing
def _table(data: dict[str, Any], key: str, allowed: tuple[str, ...]) -> dict[str, Any]:
    raw = data.get(key, {})
    if not isinstance(raw, dict):
        raise ConfigError(key, f"must be a table (got {type(raw).__name__})")
    for name in raw:
        if name not in allowed:
            raise unknown_path_error(f"{key}.{name}", f"unknown key; allowed keys are {', '.join(allowed)}")
    return raw


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(where, f"must be a finite number (got {value!r})")
    return float(value)


def _variable(base: ScenarioConfig, path: Any, raw: Any) -> Variable:
    where = f"variables.{path}"
    try:
        current = get_path(base, path)
    except ConfigError:
        note = migration_note(path) if isinstance(path, str) else None  # a removed or renamed field: say what replaces it
        raise ConfigError(where, note or "unknown config path (a design variable must name a numeric field of the scenario, e.g. control.pretension)") from None
    if isinstance(current, bool) or not isinstance(current, (int, float)):
        raise ConfigError(where, f"not a numeric field (it is {type(current).__name__}); a design variable is a number")
    if not isinstance(raw, dict):
        raise ConfigError(where, f"must be a table {{low, high, log, int, grid}} (got {type(raw).__name__})")
    allowed = ("low", "high", "log", "int", "grid")
    for key in raw:
        if key not in allowed:
            raise ConfigError(f"{where}.{key}", f"unknown key; allowed keys are {', '.join(allowed)}")
    for key in ("low", "high"):
        if key not in raw:
            raise ConfigError(where, f"needs low and high (missing {key})")
    low, high = _number(f"{where}.low", raw["low"]), _number(f"{where}.high", raw["high"])
    if not low < high:
        raise ConfigError(where, f"must satisfy low < high (got low = {low:g}, high = {high:g})")
    log, integer = raw.get("log", False), raw.get("int", isinstance(current, int))
    for key, value in (("log", log), ("int", integer)):
        if not isinstance(value, bool):
            raise ConfigError(f"{where}.{key}", f"must be true or false (got {value!r})")
    if isinstance(current, int) and not integer:
        raise ConfigError(f"{where}.int", f"{path} is an integer field: int must be true")
    if log and low <= 0.0:
        raise ConfigError(f"{where}.low", f"a log-scale variable needs low > 0 (got {low:g})")
    if integer and (low != round(low) or high != round(high)):
        raise ConfigError(where, f"an integer variable needs whole bounds (got low = {low:g}, high = {high:g})")
    grid = raw.get("grid", 0)
    require_int(f"{where}.grid", grid, 0, MAX_TRIALS, hint=", points for sampler = 'grid'")
    return Variable(path, low, high, log, integer, grid)


def _objective(i: int, raw: Any, robust: bool, known: tuple[str, ...] | None) -> Objective:
    where = f"objectives[{i}]"
    if not isinstance(raw, dict):
        raise ConfigError(where, f"must be a table {{metric, direction, aggregate, q}} (got {type(raw).__name__})")
    allowed = ("metric", "direction", "aggregate", "q")
    for key in raw:
        if key not in allowed:
            raise ConfigError(f"{where}.{key}", f"unknown key; allowed keys are {', '.join(allowed)}")
    metric = raw.get("metric")
    if not isinstance(metric, str) or not metric:
        raise ConfigError(f"{where}.metric", f"must be a metric name (metrics.json keys joined with dots; got {metric!r})")
    if metric == SUCCESS and not robust:
        raise ConfigError(f"{where}.metric", f"{SUCCESS} needs a [robustness] table with samples >= 1")
    if metric != SUCCESS and known is not None and metric not in known:
        raise ConfigError(f"{where}.metric", f"unknown metric {metric!r}; known: {', '.join(known)}")
    direction = raw.get("direction", "maximize" if metric == SUCCESS else "minimize")
    if direction not in ("minimize", "maximize"):
        raise ConfigError(f"{where}.direction", f"must be 'minimize' or 'maximize' (got {direction!r})")
    aggregate = raw.get("aggregate", "mean")
    if aggregate not in ("mean", "quantile"):
        raise ConfigError(f"{where}.aggregate", f"must be 'mean' or 'quantile' (got {aggregate!r})")
    q = raw.get("q", 0.5)
    if aggregate == "quantile" and "q" not in raw:
        raise ConfigError(f"{where}.q", "aggregate = 'quantile' needs q, with 0 <= q <= 1")
    require_range(f"{where}.q", _number(f"{where}.q", q), 0.0, 1.0, low_inclusive=True)
    return Objective(metric, direction, aggregate, float(q))


def _constraints(data: dict[str, Any]) -> tuple[Bound, ...]:
    raw = _table(data, "constraints", ("completed", "motors_not_saturated", "min_arm_clearance_m", "metrics"))
    out: list[Bound] = []
    for key, metric, bound in (("completed", COMPLETED, Bound(COMPLETED, 1.0)), ("motors_not_saturated", SATURATED, Bound(SATURATED, None, 0.0))):
        value = raw.get(key, False)
        if not isinstance(value, bool):
            raise ConfigError(f"constraints.{key}", f"must be true or false (got {value!r}); true requires {metric} = {bound.low or bound.high:g}")
        if value:
            out.append(bound)
    if "min_arm_clearance_m" in raw:
        clearance = _number("constraints.min_arm_clearance_m", raw["min_arm_clearance_m"])
        require_range("constraints.min_arm_clearance_m", clearance, 0.0, 1.0, low_inclusive=True)
        out.append(Bound(CLEARANCE, clearance))
    metrics = raw.get("metrics", {})
    if not isinstance(metrics, dict):
        raise ConfigError("constraints.metrics", f"must be a table of metric = {{min, max}} (got {type(metrics).__name__})")
    for metric, limits in metrics.items():
        where = f"constraints.metrics.{metric}"
        if not isinstance(limits, dict) or not limits or any(k not in ("min", "max") for k in limits):
            raise ConfigError(where, f"must be a table with min and/or max (got {limits!r})")
        low = None if "min" not in limits else _number(f"{where}.min", limits["min"])
        high = None if "max" not in limits else _number(f"{where}.max", limits["max"])
        if low is not None and high is not None and not low <= high:
            raise ConfigError(where, f"must satisfy min <= max (got min = {low:g}, max = {high:g})")
        out.append(Bound(metric, low, high))
    return tuple(out)


def _robustness(data: dict[str, Any]) -> Robustness:
    raw = _table(data, "robustness", ("samples", "parameters", "ranges", "min_success"))
    if not raw:
        return Robustness()
    samples: Any = raw.get("samples")
    require_int("robustness.samples", samples, 1, MAX_SAMPLES)
    names = raw.get("parameters")
    if not isinstance(names, list) or not names:
        raise ConfigError("robustness.parameters", "must be a non-empty list of registry paths (continuum-sim params lists them)")
    ranges = raw.get("ranges", {})
    if not isinstance(ranges, dict):
        raise ConfigError("robustness.ranges", f"must be a table of path = [low, high] (got {type(ranges).__name__})")
    for path in ranges:
        if path not in names:
            raise ConfigError(f"robustness.ranges.{path}", "is not among robustness.parameters")
    params: list[Uncertain] = []
    for i, path in enumerate(names):
        where = f"robustness.parameters[{i}]"
        if not isinstance(path, str) or not path:
            raise ConfigError(where, f"must be a registry parameter path (got {path!r})")
        try:
            entry = parameter(path)
        except ConfigError as exc:
            raise ConfigError(where, f"{exc.field}: {exc.message}") from None
        if path in ranges:
            pair = ranges[path]
            key = f"robustness.ranges.{path}"
            if not isinstance(pair, list) or len(pair) != 2:
                raise ConfigError(key, f"must be [low, high] (got {pair!r})")
            low, high = _number(f"{key}[0]", pair[0]), _number(f"{key}[1]", pair[1])
        elif entry.range is None:
            raise ConfigError(where, f"{path} has no plausible range in the registry ({entry.status}); give one under robustness.ranges")
        else:
            low, high = entry.range
        if not low < high:
            raise ConfigError(f"robustness.ranges.{path}", f"must satisfy low < high (got [{low:g}, {high:g}])")
        if entry.log and low <= 0.0:
            raise ConfigError(f"robustness.ranges.{path}", f"is sampled logarithmically: low must be > 0 (got {low:g})")
        params.append(Uncertain(path, float(low), float(high), entry.log))
    if len({p.path for p in params}) != len(params):
        raise ConfigError("robustness.parameters", "a parameter is listed twice")
    min_success = raw.get("min_success")
    if min_success is not None:
        require_range("robustness.min_success", _number("robustness.min_success", min_success), 0.0, 1.0)
        min_success = float(min_success)
    return Robustness(int(samples), tuple(params), min_success)


def _optimizer(data: dict[str, Any], spec_objectives: int, has_constraints: bool, variables: tuple[Variable, ...]) -> Optimizer:
    raw = _table(data, "optimizer", ("sampler", "trials", "batch", "seed"))
    sampler = raw.get("sampler", "nsga2" if spec_objectives > 1 else "tpe")
    if sampler not in SAMPLERS:
        raise ConfigError("optimizer.sampler", f"must be one of {', '.join(SAMPLERS)} (got {sampler!r})")
    if sampler == "cmaes" and (spec_objectives > 1 or has_constraints):
        raise ConfigError("optimizer.sampler", "cmaes takes one objective and no constraints; use tpe or nsga2")
    trials, batch, seed = raw.get("trials", 60), raw.get("batch", 4), raw.get("seed", 0)
    require_int("optimizer.trials", trials, 1, MAX_TRIALS)
    require_int("optimizer.batch", batch, 2 if sampler == "nsga2" else 1, 1024, hint=" (designs asked per generation)")
    require_int("optimizer.seed", seed, 0, 2**31 - 1)
    if sampler == "grid":
        missing = [v.path for v in variables if v.grid < 1]
        if missing:
            raise ConfigError(f"variables.{missing[0]}.grid", "sampler = 'grid' needs grid >= 1 points on every variable")
        points = math.prod(len(v.grid_values()) for v in variables)
        if trials > points:
            raise ConfigError("optimizer.trials", f"must satisfy 1 <= trials <= {points}, the grid's point count (got {trials})")
    return Optimizer(sampler, trials, batch, seed)


def parse_spec(data: dict[str, Any], spec_dir: str | os.PathLike[str] | None = None, source_text: str = "") -> OptimizeSpec:
    """Validate a spec dict (as read from TOML) into an ``OptimizeSpec``; ``ConfigError`` if bad."""
    allowed = ("base", "config", "variables", "objectives", "constraints", "robustness", "optimizer", "evaluation")
    check_keys(data, allowed)
    base, base_path = spec_base(data, spec_dir, with_settings=True)
    settings = data.get("config", {})  # kept as written (the best designs' TOMLs repeat it)

    raw_vars = data.get("variables")
    if not isinstance(raw_vars, dict) or not raw_vars:
        raise ConfigError("variables", "must be a non-empty table of config path = {low, high}, e.g. \"control.pretension\" = {low = 15, high = 50}")
    variables = tuple(_variable(base, path, raw) for path, raw in raw_vars.items())

    evaluation = parse_evaluation(data.get("evaluation", {"kind": "scenario"}))
    robustness = _robustness(data)
    for u in robustness.parameters:
        if u.path in raw_vars:
            raise ConfigError("robustness.parameters", f"{u.path} is also a design variable")
    known = evaluation.known_metrics()
    raw_obj = data.get("objectives")
    if not isinstance(raw_obj, list) or not raw_obj:
        raise ConfigError("objectives", "must be a non-empty list of [[objectives]] tables with a metric")
    objectives = tuple(_objective(i, raw, robustness.samples > 0, known) for i, raw in enumerate(raw_obj))
    if len({o.label for o in objectives}) != len(objectives):
        raise ConfigError("objectives", "an objective is listed twice")
    constraints = _constraints(data)
    if known is not None:
        for c in constraints:
            if c.metric not in known:
                raise ConfigError("constraints", f"metric {c.metric!r} is not produced by {evaluation.kind}; known: {', '.join(known)}")
    if robustness.min_success is not None and not constraints:
        raise ConfigError("robustness.min_success", "needs [constraints]: a sample's success is that every constraint holds")
    has_constraints = bool(constraints) and (not robustness.samples or robustness.min_success is not None)
    optimizer = _optimizer(data, len(objectives), has_constraints, variables)
    if optimizer.trials * max(1, robustness.samples) > 100_000:
        raise ConfigError("optimizer.trials", f"{optimizer.trials} trials x {robustness.samples} samples is more than 100000 evaluations")
    return OptimizeSpec(base, variables, objectives, constraints, robustness, optimizer, evaluation, base_path, source_text, settings)


def load_spec(path: str | os.PathLike[str]) -> OptimizeSpec:
    """Read and validate a study spec TOML; errors name the file and the field."""
    path = Path(path)
    text = read_config_text(path)
    data = parse_toml_text(text, str(path))
    try:
        return parse_spec(data, path.parent, text)
    except ConfigError as exc:
        raise exc.under(f"{path}: ") from None


def with_optimizer(spec: OptimizeSpec, *, trials: int | None = None, seed: int | None = None) -> OptimizeSpec:
    """``spec`` with ``optimizer.trials`` and/or ``optimizer.seed`` replaced (``--trials``, ``--seed``), checked as the spec's own.

    The spec file stays as written; the study's identity (what a folder must match to be
    resumed) takes the new values, so another seed is another study.
    """
    import dataclasses

    opt = spec.optimizer
    if trials is not None:
        require_int("--trials", trials, 1, MAX_TRIALS)
        if opt.sampler == "grid":
            points = math.prod(len(v.grid_values()) for v in spec.variables)
            if trials > points:
                raise ConfigError("--trials", f"must satisfy 1 <= trials <= {points}, the grid's point count (got {trials})")
        if trials * spec.n_samples > 100_000:
            raise ConfigError("--trials", f"{trials} trials x {spec.robustness.samples} samples is more than 100000 evaluations")
        opt = dataclasses.replace(opt, trials=trials)
    if seed is not None:
        require_int("--seed", seed, 0, 2**31 - 1)
        opt = dataclasses.replace(opt, seed=seed)
    return dataclasses.replace(spec, optimizer=opt)
