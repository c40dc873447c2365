"""The uncertainty method's options and its success criterion (the spec's ``[uncertainty]`` and ``[success]``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..configio import ConfigError, require_int

COMPLETED = "task.completed"
FAILURE = "task.failure"


@dataclass(frozen=True)
class UncertaintyOptions:
    samples: int = 64  # Latin hypercube points, one evaluation each
    seed: int = 0

    def __post_init__(self) -> None:
        require_int("uncertainty.samples", self.samples, 4, 20_000)
        require_int("uncertainty.seed", self.seed, 0)


@dataclass(frozen=True)
class Bound:
    """One success condition: ``low <= metric <= high`` (either side may be open)."""

    metric: str
    low: float | None
    high: float | None

    def holds(self, value: Any) -> bool:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            return False
        return (self.low is None or value >= self.low) and (self.high is None or value <= self.high)

    def text(self) -> str:
        if self.low is not None and self.high is not None:
            return f"{self.low:g} <= {self.metric} <= {self.high:g}"
        return f"{self.metric} <= {self.high:g}" if self.high is not None else f"{self.metric} >= {self.low:g}"


def parse_success(raw: Any) -> tuple[Bound, ...]:
    """The ``[success]`` table: ``"metric" = {max = 2.5}`` (``min`` and/or ``max``)."""
    if raw is None:
        return ()
    if not isinstance(raw, dict):
        raise ConfigError("success", f"must be a table of metric = {{min = .., max = ..}} (got {type(raw).__name__})")
    bounds = []
    for metric, limits in raw.items():
        where = f"success.{metric}"
        if not isinstance(limits, dict) or not limits or set(limits) - {"min", "max"}:
            raise ConfigError(where, f"must be a table with min and/or max (got {limits!r})")
        values = {}
        for key, v in limits.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"{where}.{key}", f"must be a finite number (got {v!r})")
            values[key] = float(v)
        if "min" in values and "max" in values and not values["min"] <= values["max"]:
            raise ConfigError(where, f"must satisfy min <= max (got {values['min']:g} > {values['max']:g})")
        bounds.append(Bound(metric, values.get("min"), values.get("max")))
    return tuple(bounds)
