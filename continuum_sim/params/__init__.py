"""The parameter registry (``registry``) and its ``continuum-sim params`` command (``cli``)."""

from .registry import REGISTRY, STATUSES, Parameter, apply, assumed, parameter, parse_overrides, records, values

__all__ = ["REGISTRY", "STATUSES", "Parameter", "apply", "assumed", "parameter", "parse_overrides", "records", "values"]
