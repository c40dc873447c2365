"""Global sensitivity of the task to the assumed plant parameters.

``load_spec`` validates a study spec; ``run_study`` samples the parameters over their
registry ranges with SALib (Morris screening, Sobol' indices), evaluates the samples on
the sweep backends (resumable) and writes the report. See docs/sensitivity.md.
"""

from .spec import DEFAULT_METRICS, SensitivitySpec, load_spec, parse_spec
from .study import StudyResult, run_study

__all__ = ["DEFAULT_METRICS", "SensitivitySpec", "StudyResult", "load_spec", "parse_spec", "run_study"]
