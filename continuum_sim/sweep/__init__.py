"""Parameter sweeps (SPEC §9): a grid over config paths, one evaluation per variant.

``load_spec`` validates a sweep spec before any work; ``run_sweep`` evaluates the
variants not yet recorded in the results folder (resumable), locally or on Ray, and
rebuilds the results table and plots. See README "Parameter sweeps".
"""

from .evaluations import KINDS, Evaluation, EvaluationFailed, GravitySag, Scenario, Stage, TipDeflection
from .runner import SweepResult, run_sweep
from .spec import GridAxis, SweepSpec, Variant, load_spec, parse_spec

__all__ = [
    "KINDS",
    "Evaluation",
    "EvaluationFailed",
    "GravitySag",
    "GridAxis",
    "Scenario",
    "Stage",
    "SweepResult",
    "SweepSpec",
    "TipDeflection",
    "Variant",
    "load_spec",
    "parse_spec",
    "run_sweep",
]
