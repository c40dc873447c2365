"""``continuum-sim`` command line. Bad input → one line on stderr and exit code 2 (docs/errors.md).

``boundary`` (the error boundary and ``main``), ``parser`` (every subcommand), the commands by
kind (``geometry_commands``, ``run_commands``, ``params``; studies register their own from
their packages), ``errors`` (exit codes).
"""

from .boundary import main
from .errors import (
    EXIT_BROKEN_PIPE,
    EXIT_DIVERGED,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_NEGATIVE,
    EXIT_OK,
    EXIT_RESOURCES,
    EXIT_TERMINATED,
    EXIT_USAGE,
    UsageError,
)
from .parser import build_parser

__all__ = ["EXIT_BROKEN_PIPE", "EXIT_DIVERGED", "EXIT_INTERNAL", "EXIT_INTERRUPTED", "EXIT_NEGATIVE", "EXIT_OK",
           "EXIT_RESOURCES", "EXIT_TERMINATED", "EXIT_USAGE", "UsageError", "build_parser", "main"]
