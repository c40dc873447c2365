"""numba helpers shared by the compiled per-step kernels (``friction``, ``plant``)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any


def jit(fn: Callable[..., Any]) -> Any:
    """``fn`` compiled by numba in nopython mode, cached on disk (no fast-math: results are IEEE exact)."""
    from numba import njit

    return njit(cache=True, fastmath=False, nogil=True)(fn)


def jit_in_place(namespace: dict[str, Any], names: tuple[str, ...]) -> None:
    """Rebind each of ``names`` in a module's ``namespace`` (its ``globals()``) to its jitted
    version, in order, so kernels that call those helpers call the compiled ones in nopython mode."""
    for name in names:
        namespace[name] = jit(namespace[name])


def mujoco_symbols(*names: str) -> tuple[int, ...] | None:
    """The C addresses of MuJoCo functions ``names`` in the library the bindings loaded (the
    compiled kernels call them directly); None where the library or a symbol is not found,
    and the caller takes its Python path."""
    import ctypes
    import glob
    import os

    import mujoco

    here = os.path.dirname(mujoco.__file__)
    libraries = sorted(p for pattern in ("libmujoco*.so*", "libmujoco*.dylib", "mujoco*.dll")
                       for p in glob.glob(os.path.join(here, pattern)))
    for path in libraries:
        try:
            lib = ctypes.CDLL(path)
            addresses = tuple(int(ctypes.cast(getattr(lib, name), ctypes.c_void_p).value or 0) for name in names)
        except (OSError, AttributeError):
            continue
        if all(addresses):
            return addresses
    return None


@contextmanager
def sigint_deferred() -> Iterator[None]:
    """While the block runs (a numba compile, or a load from its cache), Ctrl-C only records
    itself; a ``KeyboardInterrupt`` is raised once the block is done.

    llvmlite's own ctypes callbacks swallow a KeyboardInterrupt raised inside them (seen: a
    cold-cache compile ran on after Ctrl-C). Only in the main thread, and only while Python's
    default handler is installed.
    """
    import signal
    import threading

    interrupted: list[int] = []
    restore = None
    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        restore = signal.signal(signal.SIGINT, lambda signum, _frame: interrupted.append(signum))
    try:
        yield
    finally:
        if restore is not None:
            signal.signal(signal.SIGINT, restore)
    if interrupted:
        raise KeyboardInterrupt
