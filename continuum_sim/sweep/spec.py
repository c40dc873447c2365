"""Sweep spec: which config fields to vary, over which values, evaluated how.

A spec is a TOML file::

    base = "my_scenario.toml"            # optional, relative to the spec file
    metrics = ["sag_mm", "max_cable_tension_n"]   # optional: default all of the evaluation's

    [grid]                               # cartesian product, last key varies fastest
    "model.stiffness_scale" = {start = 0.5, stop = 16.0, num = 11, scale = "log"}
    "arm.sections.2.hinge_thickness" = [0.0008, 0.001]

    [evaluation]
    kind = "gravity_sag"                 # gravity_sag | tip_deflection | scenario | stage
    q_deg = [60, 0, 30, 0, 0, 0]

Everything is checked here, before any simulation starts: grid paths must name numeric
fields of the base ``ScenarioConfig``, values must be numbers of the field's type, every
variant's config must validate, the evaluation and metrics must be known. Failures are
one-line ``ConfigError``s naming the field.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, get_type_hints

import numpy as np

from ..configio import ConfigError, from_dict, get_path, migration_note, parse_toml_text, read_config_text, replace_path, to_dict, unknown_path_error
from ..scenario.config import ScenarioConfig, merged
from .evaluations import Evaluation, parse_evaluation

Number = int | float
MAX_VARIANTS = 100_000


@dataclass(frozen=True)
class GridAxis:
    """One swept field: its dotted path and the values it takes, in order."""

    path: str
    values: tuple[Number, ...]
    log: bool = False  # spaced logarithmically (plots use a log axis)


@dataclass(frozen=True)
class Variant:
    """One point of the grid: its position, parameter values and stable id."""

    index: int
    params: tuple[tuple[str, Number], ...]
    variant_id: str

    @property
    def param_dict(self) -> dict[str, Number]:
        return dict(self.params)


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: base config, grid axes, evaluation, metrics to tabulate."""

    base: ScenarioConfig
    axes: tuple[GridAxis, ...]
    evaluation: Evaluation
    metrics: tuple[str, ...]
    base_path: str | None = None
    source_text: str = ""

    @property
    def paths(self) -> tuple[str, ...]:
        return tuple(axis.path for axis in self.axes)

    @property
    def n_variants(self) -> int:
        return math.prod(len(axis.values) for axis in self.axes)

    def variants(self, progress: bool = False) -> list[Variant]:
        """All variants in grid order (cartesian product, last axis fastest).

        Made once per spec (10^5 variants: ~2-4 s of hashing; the run, the table and the
        plots all ask), with a bar on stderr above 20,000 when ``progress``.
        """
        cached = self.__dict__.get("_variants")
        if cached is None:
            from tqdm import tqdm

            out = []
            evaluation = self.evaluation.to_dict()  # once, not per variant (10^5 variants: 12 s -> 2 s)
            combos = np.ndindex(*[len(a.values) for a in self.axes])
            for index, combo in enumerate(tqdm(combos, total=self.n_variants, desc="listing variants", unit="variant",
                                               disable=not progress or self.n_variants < 20_000, leave=False,
                                               mininterval=0.5, file=sys.stderr, dynamic_ncols=True)):
                params = tuple((axis.path, axis.values[i]) for axis, i in zip(self.axes, combo))
                out.append(Variant(index, params, variant_id(params, self.evaluation, evaluation)))
            cached = self.__dict__["_variants"] = tuple(out)  # frozen: not a field (equality, hashing unchanged)
        return list(cached)

    def config_for(self, variant: Variant) -> ScenarioConfig:
        """The base config with the variant's values set (checked valid by ``check_variants``).

        Equal to ``apply_params`` (a rebuild from the dict, ~15 ms) in ~30 µs: only the
        dataclasses on the swept paths are re-made.
        """
        return _replaced(self.base, [(path.split("."), value) for path, value in variant.params]) if variant.params else self.base

    def identity(self) -> dict[str, Any]:
        """What must match for a results folder to be resumed: base, grid, evaluation."""
        return {
            "base": to_dict(self.base),
            "grid": {axis.path: list(axis.values) for axis in self.axes},
            "evaluation": self.evaluation.to_dict(),
        }


def variant_id(params: tuple[tuple[str, Number], ...], evaluation: Evaluation, evaluation_dict: dict[str, Any] | None = None) -> str:
    """Stable id: a hash of the parameter values and the evaluation spec (``evaluation_dict``: its precomputed ``to_dict()``)."""
    described = evaluation.to_dict() if evaluation_dict is None else evaluation_dict
    text = json.dumps({"params": [[p, v] for p, v in params], "evaluation": described}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def apply_params(base: ScenarioConfig, params) -> ScenarioConfig:
    config = base
    for path, value in params:
        config = replace_path(config, path, value)
    return config


# ------------------------------------------------------------------------ parsing
def _axis_values(path: str, raw: Any, kind: type) -> tuple[tuple[Number, ...], bool]:
    where = f"grid.{path}"
    log = False
    if isinstance(raw, dict):
        allowed = {"start", "stop", "num", "scale"}
        for key in raw:
            if key not in allowed:
                raise ConfigError(f"{where}.{key}", f"unknown key; allowed keys are {', '.join(sorted(allowed))}")
        for key in ("start", "stop", "num"):
            if key not in raw:
                raise ConfigError(where, f"a range needs start, stop and num (missing {key})")
        start, stop, num = raw["start"], raw["stop"], raw["num"]
        for key, value in (("start", start), ("stop", stop)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError(f"{where}.{key}", f"must be a finite number (got {value!r})")
        if isinstance(num, bool) or not isinstance(num, int) or not 1 <= num <= MAX_VARIANTS:
            raise ConfigError(f"{where}.num", f"must be an integer in [1, {MAX_VARIANTS}] (got {num!r})")
        scale = raw.get("scale", "linear")
        if scale not in ("linear", "log"):
            raise ConfigError(f"{where}.scale", f"must be 'linear' or 'log' (got {scale!r})")
        if scale == "log":
            if start <= 0 or stop <= 0:
                raise ConfigError(where, f"a log range needs start > 0 and stop > 0 (got {start!r}, {stop!r})")
            values = np.geomspace(float(start), float(stop), num)
            log = True
        else:
            values = np.linspace(float(start), float(stop), num)
        # 12 significant digits: geomspace's 3.999999999999999 becomes 4.0 (stable ids, clean tables)
        raw_values: list[Any] = [float(f"{v:.12g}") for v in values]
    elif isinstance(raw, list):
        raw_values = raw
    else:
        raise ConfigError(where, f"must be a list of numbers or a table {{start, stop, num, scale}} (got {type(raw).__name__})")
    if not raw_values:
        raise ConfigError(where, "empty list of values: the grid would have no variants")
    out: list[Number] = []
    for i, value in enumerate(raw_values):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where}[{i}]", f"must be a number (got {type(value).__name__} {value!r})")
        if not math.isfinite(value):
            raise ConfigError(f"{where}[{i}]", f"must be a finite number (got {value!r})")
        if kind is int:
            if float(value) != round(value):
                raise ConfigError(f"{where}[{i}]", f"{path} is an integer field (got {value!r})")
            out.append(int(round(value)))
        else:
            out.append(float(value))
    if len(set(out)) != len(out):
        dup = next(v for v in out if out.count(v) > 1)
        raise ConfigError(where, f"value {dup!r} appears twice: every variant must be distinct")
    return tuple(out), log


def _lookup(base: ScenarioConfig, path: str) -> Any:
    """The base value at ``path``; an unknown path names the bad part and the choices there."""
    try:
        return get_path(base, path)
    except ConfigError:
        note = migration_note(path)
        if note is not None:  # a removed or renamed field: say what replaces it
            raise ConfigError(f"grid.{path}", note) from None
    node: Any = to_dict(base)
    parts = path.split(".")
    for i, part in enumerate(parts):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            where = ".".join(parts[:i]) or "the scenario configuration"
            if isinstance(node, dict):
                choices = "fields " + ", ".join(node)
            elif isinstance(node, list):
                choices = f"indices 0 to {len(node) - 1}"
            else:
                choices = "no fields: it is a value"
            raise ConfigError(f"grid.{path}", f"unknown parameter path: {where} has no {part!r} (it has {choices})")
    raise ConfigError(f"grid.{path}", "unknown parameter path")


def check_keys(data: dict[str, Any], allowed: tuple[str, ...]) -> None:
    """A study spec's top-level keys: each one of ``allowed`` (sweep, sensitivity and optimize specs)."""
    for key in data:
        if key not in allowed:
            raise unknown_path_error(key, f"unknown key; allowed keys are {', '.join(allowed)}")


def spec_base(data: dict[str, Any], spec_dir: str | os.PathLike[str] | None,
              with_settings: bool = False) -> tuple[ScenarioConfig, str | None]:
    """A study spec's base scenario: ``base`` (a scenario TOML, relative to the spec's folder) or the shipped
    defaults; with ``with_settings``, the spec's ``[config]`` table merged over it. Returns (config, resolved path)."""
    base_path = data.get("base")
    if base_path is None:
        base = ScenarioConfig.default()
    else:
        if not isinstance(base_path, str) or not base_path:
            raise ConfigError("base", f"must be a path to a scenario TOML file (got {base_path!r})")
        resolved = Path(base_path)
        if not resolved.is_absolute() and spec_dir is not None:
            resolved = Path(spec_dir) / resolved
        if not resolved.is_file():
            raise ConfigError("base", f"scenario file {str(resolved)!r} not found")
        base = ScenarioConfig.from_toml(resolved)
        base_path = str(resolved)
    if with_settings:
        settings = data.get("config", {})
        if not isinstance(settings, dict):
            raise ConfigError("config", f"must be a table of scenario settings (got {type(settings).__name__})")
        try:
            base = merged(base, settings)
        except ConfigError as exc:
            raise exc.under("config") from None
    return base, base_path


def parse_spec(
    data: dict[str, Any], spec_dir: str | os.PathLike[str] | None = None, source_text: str = "", progress: bool = False
) -> SweepSpec:
    """Validate a spec dict (as read from TOML) into a ``SweepSpec``; ``ConfigError`` if bad."""
    allowed = ("base", "metrics", "grid", "evaluation")
    check_keys(data, allowed)
    base, base_path = spec_base(data, spec_dir)

    grid = data.get("grid")
    if grid is None:
        raise ConfigError("grid", "missing: a sweep needs a [grid] table of parameter paths")
    if not isinstance(grid, dict):
        raise ConfigError("grid", f"must be a table of parameter paths (got {type(grid).__name__})")
    if not grid:
        raise ConfigError("grid", "empty: name at least one parameter path, e.g. \"model.stiffness_scale\" = [0.5, 1, 2]")
    axes = []
    for path, raw in grid.items():
        current = _lookup(base, path)
        if isinstance(current, bool) or not isinstance(current, (int, float)):
            what = "a table" if isinstance(current, dict) else "a list" if isinstance(current, list) else type(current).__name__
            raise ConfigError(f"grid.{path}", f"not a numeric field (it is {what}); sweep a number")
        values, log = _axis_values(path, raw, int if isinstance(current, int) else float)
        axes.append(GridAxis(path, values, log))
    n = math.prod(len(a.values) for a in axes)
    if n > MAX_VARIANTS:
        raise ConfigError("grid", f"{n} variants is more than the limit of {MAX_VARIANTS}")

    if "evaluation" not in data:
        raise ConfigError("evaluation", "missing: a sweep needs an [evaluation] table with a kind")
    evaluation = parse_evaluation(data["evaluation"])

    metrics_raw = data.get("metrics")
    if metrics_raw is None:
        metrics = evaluation.default_metrics()
    else:
        if not isinstance(metrics_raw, list) or not metrics_raw:
            raise ConfigError("metrics", "must be a non-empty list of metric names")
        for i, name in enumerate(metrics_raw):
            if not isinstance(name, str) or not name:
                raise ConfigError(f"metrics[{i}]", f"must be a metric name (got {name!r})")
        known = evaluation.known_metrics()
        for i, name in enumerate(metrics_raw):
            if known is not None and name not in known:
                raise ConfigError(f"metrics[{i}]", f"unknown metric {name!r} for {evaluation.kind}; known: {', '.join(known)}")
        if len(set(metrics_raw)) != len(metrics_raw):
            raise ConfigError("metrics", "a metric is listed twice")
        metrics = tuple(metrics_raw)

    spec = SweepSpec(base, tuple(axes), evaluation, metrics, base_path, source_text)
    check_variants(spec, progress=progress)
    return spec


# Parts of the scenario config that checks combine (arm × model segment count, model
# timestep × control rate, the evaluation's pose × arm limits). Axes in other parts
# (layout, scene, plan, simulation) only meet their own part's checks.
COUPLED_PARTS = ("arm", "model", "control")
REBUILDS = {"count": 0}  # full config rebuilds (from_dict) by the last check_variants: tests assert O(sum of axis sizes)


def _set_path(data: dict[str, Any], path: str, value: Any) -> None:
    node: Any = data
    parts = path.split(".")
    for part in parts[:-1]:
        node = node[int(part)] if isinstance(node, list) else node[part]
    last = parts[-1]
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value


def _variant_config(base: ScenarioConfig, base_dict: dict[str, Any], params) -> ScenarioConfig:
    """``apply_params`` rebuilding only the touched parts from their dicts (every field converted and checked)."""
    REBUILDS["count"] += 1
    touched: dict[str, dict[str, Any]] = {}
    for path, value in params:
        part, _, rest = path.partition(".")
        if part not in touched:
            touched[part] = copy.deepcopy(base_dict[part])
        _set_path(touched[part], rest, value)
    hints = get_type_hints(ScenarioConfig)
    parts = {part: from_dict(hints[part], data, prefix=part) for part, data in touched.items()}
    return dataclasses.replace(base, **parts) if parts else base


def _replaced(obj: Any, changes: list[tuple[list[str], Any]]) -> Any:
    """``obj`` with every (path parts, value) of ``changes`` set at once, by ``dataclasses.replace``.

    Only the dataclasses on the changed paths are re-made (their own checks run, with all
    the changes in place together): ~30 µs instead of ~1 ms for a rebuild from the dict.
    Values must already be of the field's type (each was rebuilt alone first).
    """
    by_head: dict[str, list[tuple[list[str], Any]]] = {}
    for parts, value in changes:
        by_head.setdefault(parts[0], []).append((parts[1:], value))
    new: dict[str, Any] = {}
    for head, subs in by_head.items():
        child = obj[int(head)] if isinstance(obj, (tuple, list)) else getattr(obj, head)
        new[head] = subs[0][1] if not subs[0][0] else _replaced(child, subs)
    if isinstance(obj, (tuple, list)):
        items = list(obj)
        for head, value in new.items():
            items[int(head)] = value
        return type(obj)(items)
    cls = type(obj)
    names = _INIT_FIELDS.get(cls)
    if names is None:
        names = _INIT_FIELDS[cls] = tuple(f.name for f in dataclasses.fields(cls) if f.init)
    return cls(**{name: new[name] if name in new else getattr(obj, name) for name in names})  # dataclasses.replace, 3× faster


_INIT_FIELDS: dict[type, tuple[str, ...]] = {}


def _check_config(config: ScenarioConfig, evaluation: Evaluation) -> None:
    from ..limits import check_model_geometry, check_scenario

    if evaluation.static:
        check_model_geometry(config)
    else:
        check_scenario(config)
    evaluation.check(config)


def check_variants(spec: SweepSpec, progress: bool = False) -> None:
    """Every variant must be a valid config the evaluation accepts; ``ConfigError`` naming the first that is not.

    Two passes, both far below one rebuild per variant (a 10^5-variant grid took 207 s):

    1. every value of every axis alone on the base config, rebuilt from its dict (all field
       conversions and checks): sum of the axis sizes rebuilds;
    2. combinations, only of axes that one check can see together: axes of one part, or
       of the coupled parts (``COUPLED_PARTS``: arm × model × control); other parts never
       meet in a check. These are re-made by ``dataclasses.replace`` of the changed
       dataclasses only (~20× cheaper than a rebuild), and a failing one is rebuilt
       from its dict so the message names the field as pass 1 does.

    Same verdict as checking each variant whole. A bar (stderr) shows progress when there
    are more than 2,000 checks.
    """
    from tqdm import tqdm

    axes = spec.axes
    REBUILDS["count"] = 0
    by_part: dict[str, list[int]] = {}
    for i, axis in enumerate(axes):
        part = axis.path.split(".")[0]
        by_part.setdefault("coupled" if part in COUPLED_PARTS else part, []).append(i)
    groups = [group for group in by_part.values() if len(group) > 1]
    singles = sum(len(axis.values) for axis in axes) + 1
    total = singles + sum(math.prod(len(axes[i].values) for i in group) for group in groups)
    base_dict = to_dict(spec.base)
    shape = [len(a.values) for a in axes]
    split = [axis.path.split(".") for axis in axes]

    def fail(exc: ConfigError, picks: list[tuple[int, int]]) -> ConfigError:
        position = [0] * len(axes)
        for i, j in picks:
            position[i] = j
        index = int(np.ravel_multi_index(position, shape)) if axes else 0
        label = ", ".join(f"{axes[i].path} = {axes[i].values[j]!r}" for i, j in picks) or "the base configuration"
        return ConfigError(exc.field, f"{exc.message} (variant {index}: {label})")

    def full_check(picks: list[tuple[int, int]]) -> None:
        params = tuple((axes[i].path, axes[i].values[j]) for i, j in picks)
        try:
            _check_config(_variant_config(spec.base, base_dict, params), spec.evaluation)
        except ConfigError as exc:
            raise fail(exc, picks) from None

    with tqdm(total=total, desc="checking variants", unit="check", disable=not progress or total <= 2_000, mininterval=0.5,
              file=sys.stderr, dynamic_ncols=True) as bar:
        full_check([])
        bar.update(1)
        for i, axis in enumerate(axes):
            for j in range(len(axis.values)):
                full_check([(i, j)])
                bar.update(1)
        for group in groups:
            for combo in np.ndindex(*[shape[i] for i in group]):
                picks = list(zip(group, combo))
                changes = [(split[i], axes[i].values[j]) for i, j in picks]
                try:
                    _check_config(_replaced(spec.base, changes), spec.evaluation)
                except ConfigError:
                    full_check(picks)  # the message as a rebuild gives it (field names with their part)
                    raise  # pragma: no cover - a rebuild accepts what replace refused: re-raise replace's error
                bar.update(1)


def load_spec(path: str | os.PathLike[str], progress: bool = False) -> SweepSpec:
    """Read and validate a sweep spec TOML; errors name the file and the field."""
    path = Path(path)
    text = read_config_text(path)
    data = parse_toml_text(text, str(path))
    try:
        return parse_spec(data, path.parent, text, progress=progress)
    except ConfigError as exc:
        raise exc.under(f"{path}: ") from None
