"""The one error boundary of every command: bad input one line and exit 2, divergence exit 3, never a traceback
unless ``--debug`` (docs/errors.md, "Writing a command")."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from ..configio import ConfigError
from .errors import (
    EXIT_BROKEN_PIPE,
    EXIT_DIVERGED,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_RESOURCES,
    EXIT_TERMINATED,
    EXIT_USAGE,
    Terminated,
    UsageError,
    clip_line,
)
from .parser import build_parser


def _check_finite_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Every float option of the chosen command must be finite (argparse's float() accepts nan and inf)."""
    import math

    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))  # noqa: SLF001
    command = sub.choices.get(args.command)
    if command is None:
        return
    for action in command._actions:  # noqa: SLF001
        if action.type is not float:
            continue
        value = getattr(args, action.dest, None)
        name = action.option_strings[0] if action.option_strings else action.metavar or action.dest
        if action.nargs is None and isinstance(value, list):  # argparse turns `--tol=--` into []
            raise UsageError(f"{name}: expected one number")
        values = value if isinstance(value, (list, tuple)) else [value]
        for v in values:
            if isinstance(v, float) and not math.isfinite(v):
                raise UsageError(f"{name}: must be a finite number (got {v!r})")


def _check_environment(args: argparse.Namespace) -> None:
    """Environment variables read later, deep inside an import: check them before any work.

    Only commands that render choose (and check) a GL backend; the others run with GL
    disabled, so a missing or broken GL library never matters to them (docs/errors.md).
    """
    import os

    from ..glbackend import VALID_BACKENDS, GLBackendError, disable_gl, require_gl_backend

    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    if requested and requested not in VALID_BACKENDS:
        raise UsageError(f"MUJOCO_GL: must be one of {', '.join(VALID_BACKENDS)} or unset (got {requested[:40]!r})")
    if args.command == "view" or getattr(args, "video", False):
        try:
            require_gl_backend()
        except GLBackendError as exc:
            raise UsageError(str(exc)) from None
    else:
        disable_gl()


def _signal_cause(exc: BaseException) -> BaseException | None:
    """The Ctrl-C or SIGTERM behind ``exc`` (its cause or context chain), if any."""
    seen: set[int] = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        seen.add(id(link))
        if isinstance(link, KeyboardInterrupt | Terminated):
            return link
        link = link.__cause__ or link.__context__
    return None


def _is_divergence(exc: BaseException) -> bool:
    return any(cls.__name__ == "SimulationDiverged" for cls in type(exc).__mro__)


def _os_error_line(exc: OSError) -> tuple[int, str]:
    import errno

    where = exc.filename if exc.filename is not None else ""
    reason = exc.strerror or str(exc) or type(exc).__name__
    text = f"{where}: {reason}" if where else reason
    if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.ENOMEM):
        return EXIT_RESOURCES, f"could not write results: {text}"
    return EXIT_USAGE, text


def _silence_stdout() -> None:
    """After a broken pipe: point stdout at /dev/null so the interpreter's final flush is quiet."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


class _WarningSummary:
    """Numeric warnings (overflow in ik, ...) as one line at the end instead of a page each."""

    def __init__(self) -> None:
        self.count = 0
        self.first: str | None = None

    def show(self, message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ARG002
        self.count += 1
        if self.first is None:
            self.first = f"{category.__name__}: {message}"

    def line(self, prog: str) -> str | None:
        if not self.count:
            return None
        more = f" ({self.count} warnings in all; --debug shows each)" if self.count > 1 else ""
        return f"{prog}: warning: {clip_line(self.first or '', 200)}{more}"


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; returns the exit code (docs/errors.md). ``--debug`` anywhere shows tracebacks."""
    import os
    import signal
    import threading
    import traceback
    import warnings

    argv = list(sys.argv[1:] if argv is None else argv)
    argv_given = list(argv)
    debug = "--debug" in argv or os.environ.get("CONTINUUM_SIM_DEBUG", "") not in ("", "0")
    argv = [a for a in argv if a != "--debug"]
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a bad argument (2, one line already printed)
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    prog = f"continuum-sim {args.command}"
    from .. import provenance

    provenance.set_invocation(["continuum-sim", *argv_given], command=args.command)  # provenance.json's argv and command

    def fail(code: int, message: str) -> int:
        if debug:
            traceback.print_exc()
        try:
            print(f"{prog}: {clip_line(message)}", file=sys.stderr)
        except (OSError, ValueError):
            pass
        return code

    def on_sigterm(signum, frame) -> None:  # noqa: ARG001
        raise Terminated

    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, on_sigterm) if in_main_thread else None
    summary = _WarningSummary()
    old_limit = sys.getrecursionlimit()
    # MuJoCo's model builder (dm_control) recurses once per nested body: 200 segments per
    # section (the documented maximum) nest 600+ bodies; Python 3.11+ frames do not use the C stack.
    sys.setrecursionlimit(max(old_limit, 10_000))
    gl_environment = {name: os.environ.get(name) for name in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}  # restored after
    try:
        with warnings.catch_warnings():
            if not debug:
                warnings.showwarning = summary.show
            _check_environment(args)
            _check_finite_args(parser, args)
            if isinstance(getattr(args, "out", None), str):  # every command's --out, file or folder
                from ..configio import check_output_path

                check_output_path(args.out, "--out")
            code = int(args.func(args) or 0)
            sys.stdout.flush()
        note = summary.line(prog)
        if note:
            print(note, file=sys.stderr)
        return code
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        return fail(EXIT_INTERRUPTED, "interrupted (Ctrl-C)")
    except Terminated:
        return fail(EXIT_TERMINATED, "terminated (SIGTERM)")
    except (ConfigError, UsageError) as exc:
        return fail(EXIT_USAGE, f"error: {exc}")
    except MemoryError:
        return fail(EXIT_RESOURCES, "error: out of memory; reduce the sizes this command was asked for")
    except OSError as exc:
        code, text = _os_error_line(exc)
        return fail(code, f"error: {text}")
    except RecursionError:
        return fail(EXIT_USAGE, "error: input nested too deeply (recursion limit reached)")
    except Exception as exc:  # noqa: BLE001 - the boundary: one line, never a traceback unless --debug
        # A signal handler's exception raised while a compiled (numba) function runs comes back as
        # SystemError("... returned a result with an exception set") with the real one as its cause.
        cause = _signal_cause(exc)
        if isinstance(cause, KeyboardInterrupt):
            return fail(EXIT_INTERRUPTED, "interrupted (Ctrl-C)")
        if isinstance(cause, Terminated):
            return fail(EXIT_TERMINATED, "terminated (SIGTERM)")
        if _is_divergence(exc):
            return fail(EXIT_DIVERGED, f"error: {exc}")
        return fail(EXIT_INTERNAL, f"internal error: {type(exc).__name__}: {clip_line(str(exc), 250)} (rerun with --debug for the traceback)")
    finally:
        provenance.set_invocation(None)
        sys.setrecursionlimit(old_limit)
        for name, value in gl_environment.items():  # main() called in-process (tests, scripts) leaves it as it was
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        if in_main_thread and previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
