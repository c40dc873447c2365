"""What a sweep measures per variant: the evaluation kinds, their parameters and metrics.

* ``gravity_sag``: one arm held open loop (cables at the planned PCC lengths with
  pre-tension) in a pose where gravity bends it; how far gravity moves the tool centre.
* ``tip_deflection``: a static force on the tip disk, cables removed (``free``: the pure
  flexure backbone) or held at their straight lengths; how far the tip moves.
* ``scenario`` / ``stage``: the whole sample-removal task, or the task up to one stage,
  through ``continuum_sim.scenario.runner.run_scenario``; its metrics, flattened.

Payload: the static evaluations carry the tool named by their ``tool`` field (default
the grinder; the same mass, centre of mass and inertia as the task scene's tool,
``sweep.payload``) and report its mass as ``payload_kg``; the task evaluations carry
both arms' tools as the scene builds them (grinder ``model.grinder_mass``, gripper
``model.gripper_mass``, plus the sample once gripped).

The configs are frozen and validated; ``check`` validates against a variant's config
(e.g. a pose inside every variant's bending limits) before any work starts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from ..configio import ConfigError, from_dict, require_range, shorten, to_dict

# Metric names of the static evaluations, in table order.
GRAVITY_SAG_METRICS = (
    "sag_mm",
    "sag_z_mm",
    "pcc_error_mm",
    "shape_error_mm",
    "max_cable_tension_n",
    "min_cable_tension_n",
    "residual_speed_rad_s",
    "payload_kg",
)
TIP_DEFLECTION_METRICS = (
    "deflection_mm",
    "deflection_along_force_mm",
    "compliance_mm_per_n",
    "linear_prediction_mm",
    "max_cable_tension_n",
    "residual_speed_rad_s",
    "payload_kg",
)
TOOLS = ("grinder", "gripper", "none")
SCENARIO_DEFAULT_METRICS = ("sample_detached", "max_cable_tension_n", "min_arm_distance_m")


class EvaluationFailed(RuntimeError):
    """A variant could not be evaluated (diverged, unreachable plan, ...); says why.

    ``metrics`` keeps whatever was measured before the failure.
    """

    def __init__(self, reason: str, metrics: dict[str, Any] | None = None) -> None:
        super().__init__(reason)
        self.metrics = metrics or {}


@dataclass(frozen=True)
class Evaluation:
    """Base of the evaluation configs (``kind`` names the subclass)."""

    kind: ClassVar[str] = ""
    static: ClassVar[bool] = False

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, **to_dict(self)}

    def known_metrics(self) -> tuple[str, ...] | None:
        """Metric names this evaluation produces; None when only known at run time."""
        return None

    def default_metrics(self) -> tuple[str, ...]:
        known = self.known_metrics()
        return known if known is not None else SCENARIO_DEFAULT_METRICS

    def check(self, config) -> None:  # noqa: ARG002 - hook
        """Raise ``ConfigError`` if this evaluation cannot run on ``config``."""


def _check_pose(q_deg: tuple[float, ...], config) -> None:
    n = config.arm.n_sections
    if len(q_deg) != 2 * n:
        raise ConfigError("evaluation.q_deg", f"must have {2 * n} entries (θ, φ per section; got {len(q_deg)})")
    for k, section in enumerate(config.arm.sections):
        theta = q_deg[2 * k]
        if not 0.0 <= theta <= section.max_bend_deg:
            raise ConfigError(
                "evaluation.q_deg",
                f"θ{k} must satisfy 0 <= θ{k} <= max_bend_deg = {section.max_bend_deg:g} (got {theta:g})",
            )


@dataclass(frozen=True)
class GravitySag(Evaluation):
    """Open-loop hold of pose ``q_deg``: settle without gravity, then with it."""

    kind: ClassVar[str] = "gravity_sag"
    static: ClassVar[bool] = True

    q_deg: tuple[float, ...] = (60.0, 0.0, 30.0, 0.0, 0.0, 0.0)  # bent sideways: gravity has a lever
    tool: str = "grinder"  # the payload carried at the tip (see the module docstring)
    settle_s: float = 2.0  # simulated seconds per phase (without, then with gravity)

    def __post_init__(self) -> None:
        if self.tool not in TOOLS:
            raise ConfigError("tool", f"must be 'grinder', 'gripper' or 'none' (got {self.tool!r})")
        require_range("settle_s", self.settle_s, 0.0, 120.0)

    def known_metrics(self) -> tuple[str, ...]:
        return GRAVITY_SAG_METRICS

    def check(self, config) -> None:
        _check_pose(self.q_deg, config)


@dataclass(frozen=True)
class TipDeflection(Evaluation):
    """A static tip force after a settled unloaded hold; the tip's displacement."""

    kind: ClassVar[str] = "tip_deflection"
    static: ClassVar[bool] = True

    force_n: float = 0.01  # N: about 7 % of the arm length sideways for the free backbone at scale 1
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)  # world frame
    cables: str = "free"  # free: tendons removed (pure backbone); held: open-loop hold of q_deg
    gravity: bool = False
    q_deg: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    # the cable-free backbone is lightly damped: with the grinder payload ~0.5 % of the
    # static answer after 16 s (8 s: 8 %); without a payload ~0.1 % after 8 s
    settle_s: float = 16.0
    tool: str = "grinder"  # the payload carried at the tip (its weight acts when gravity is on)

    def __post_init__(self) -> None:
        require_range("force_n", self.force_n, 0.0, 1e4)
        if self.tool not in TOOLS:
            raise ConfigError("tool", f"must be 'grinder', 'gripper' or 'none' (got {self.tool!r})")
        if len(self.direction) != 3 or math.hypot(*self.direction) == 0.0:
            raise ConfigError("direction", f"must be a non-zero 3-vector (got {list(self.direction)})")
        for i, value in enumerate(self.direction):
            require_range(f"direction[{i}]", value, -1e6, 1e6, low_inclusive=True)
        if self.cables not in ("free", "held"):
            raise ConfigError("cables", f"must be 'free' or 'held' (got {self.cables!r})")
        if self.cables == "free" and any(v != 0.0 for v in self.q_deg[0::2]):
            raise ConfigError("q_deg", "with cables = 'free' nothing holds a bent pose: use all θ = 0 or cables = 'held'")
        require_range("settle_s", self.settle_s, 0.0, 120.0)

    def known_metrics(self) -> tuple[str, ...]:
        return TIP_DEFLECTION_METRICS

    def check(self, config) -> None:
        _check_pose(self.q_deg, config)


@dataclass(frozen=True)
class Scenario(Evaluation):
    """The whole task via ``run_scenario``; metrics are its nested dict, flattened with dots."""

    kind: ClassVar[str] = "scenario"
    keep_runs: bool = False  # keep each variant's run folder under <sweep>/runs/<id>/


@dataclass(frozen=True)
class Stage(Evaluation):
    """The task up to the end of ``stage`` (metrics of the stages run)."""

    kind: ClassVar[str] = "stage"
    stage: str = "milling"
    keep_runs: bool = False

    def __post_init__(self) -> None:
        from ..toolpath import STAGE_NAMES

        if not isinstance(self.stage, str) or self.stage not in STAGE_NAMES:
            raise ConfigError("stage", f"must be one of {', '.join(STAGE_NAMES)} (got {shorten(self.stage)})")


KINDS: dict[str, type[Evaluation]] = {c.kind: c for c in (GravitySag, TipDeflection, Scenario, Stage)}


def parse_evaluation(data: Any) -> Evaluation:
    """The evaluation config of a spec's ``[evaluation]`` table."""
    if not isinstance(data, dict):
        raise ConfigError("evaluation", f"must be a table with a kind (got {type(data).__name__})")
    kind = data.get("kind")
    if kind not in KINDS:
        raise ConfigError("evaluation.kind", f"must be one of {', '.join(KINDS)} (got {kind!r})")
    cls = KINDS[kind]
    params = {k: v for k, v in data.items() if k != "kind"}
    try:
        return from_dict(cls, params)
    except ConfigError as exc:
        raise exc.under("evaluation") from None


def evaluation_from_dict(data: dict[str, Any]) -> Evaluation:
    """Inverse of ``Evaluation.to_dict`` (used by worker processes)."""
    return parse_evaluation(dict(data))


__all__ = [
    "Evaluation",
    "EvaluationFailed",
    "GravitySag",
    "KINDS",
    "Scenario",
    "Stage",
    "TipDeflection",
    "evaluation_from_dict",
    "parse_evaluation",
]
