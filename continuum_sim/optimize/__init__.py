"""Design optimisation on the sweep machinery.

``load_spec`` validates a study spec (design variables, objectives, constraints,
robustness over the registry's assumed parameters, optimiser); ``run_study`` asks Optuna
for designs a generation at a time, evaluates them on the sweep backends (local processes
or Ray), records every evaluation once and resumes a killed study from its journal.
See docs/optimize.md.
"""

from .spec import OptimizeSpec, load_spec, parse_spec
from .study import StudyResult, run_study

__all__ = ["OptimizeSpec", "StudyResult", "load_spec", "parse_spec", "run_study"]
