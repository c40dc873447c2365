"""numba helpers of the compiled plant kernels: the one jit setting, stale-cache guard, Ctrl-C during compiles."""

from __future__ import annotations

import glob
import hashlib
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any


def jit(fn: Callable[..., Any]) -> Any:
    """``fn`` compiled by numba in nopython mode, cached on disk (no fast-math: IEEE arithmetic, no reassociation)."""
    from numba import njit

    return njit(cache=True, fastmath=False, nogil=True)(fn)


def jit_in_place(namespace: dict[str, Any], names: tuple[str, ...]) -> None:
    """Rebind each of ``names`` in a module's ``namespace`` (its ``globals()``) to its jitted
    version, in order, so kernels that call those helpers call the compiled ones in nopython mode."""
    for name in names:
        namespace[name] = jit(namespace[name])


def drop_stale_cache(stamp: str, sources: tuple[str, ...], cached: tuple[str, ...]) -> bool:
    """Remove numba's cache of the modules ``cached`` when any file of ``sources`` changed since it was written.

    Why: numba's cache index checks only the source file of the cached function itself; a
    kernel that calls (inlines) a function of another module, or a cfunc that calls those
    kernels, would load stale machine code after an edit elsewhere. ``stamp`` names the
    hash file. False: the cache folder is not writable (the caller compiles without caching).
    """
    here = os.path.dirname(os.path.abspath(__file__))
    folder = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(here, "__pycache__")
    digest = hashlib.sha256()
    for path in sources:
        with open(path, "rb") as fh:
            digest.update(fh.read())
    text = digest.hexdigest()
    path = os.path.join(folder, f"{stamp}.sha256")
    try:
        with open(path) as fh:
            if fh.read().strip() == text:
                return True
    except OSError:
        pass
    try:
        for module in cached:
            for old in glob.glob(os.path.join(folder, "**", f"{module}.*.nb[ic]"), recursive=True):
                os.remove(old)
        os.makedirs(folder, exist_ok=True)
        with open(path, "w") as fh:
            fh.write(text)
    except OSError:
        return False
    return True


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
