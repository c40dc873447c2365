"""What every command's failure becomes: the exit codes and the usage error (docs/errors.md)."""

from __future__ import annotations

import argparse
from typing import NoReturn


class UsageError(Exception):
    """A command-line value is invalid (message names the option)."""


EXIT_OK = 0
EXIT_NEGATIVE = 1  # the command ran but the answer is no (ik unreachable, no display for view)
EXIT_USAGE = 2  # bad input: argument, configuration, spec, path, environment, unreachable cluster
EXIT_DIVERGED = 3  # the simulation diverged (partial results kept, marked diverged)
EXIT_RESOURCES = 4  # the machine ran out of something while working (disk full, memory)
EXIT_INTERNAL = 70  # a bug: an exception nobody expected (rerun with --debug for the traceback)
EXIT_INTERRUPTED = 130  # Ctrl-C (SIGINT)
EXIT_BROKEN_PIPE = 141  # stdout closed by the reader (`continuum-sim ik ... | head`), silently
EXIT_TERMINATED = 143  # SIGTERM
MAX_LINE = 400  # characters of the one error line


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so cleanup (finally blocks) runs as for Ctrl-C."""


class OneLineParser(argparse.ArgumentParser):
    """argparse with one-line errors; subcommand parsers inherit it (argparse uses type(parent))."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {clip_line(message)} (see {self.prog} --help)\n")


def clip_line(text: str, limit: int = MAX_LINE) -> str:
    """One line, at most ``limit`` characters."""
    line = " ".join(str(text).split())
    return line if len(line) <= limit else f"{line[: limit - 1]}…"
