"""Helper processes never outlive the process that started them (docs/errors.md).

A sweep driver or a video-recording run killed with SIGKILL cannot clean up; its worker
processes must notice on their own, at once (within 1 s; measured ~10 ms):

* Linux: ``PR_SET_PDEATHSIG`` makes the kernel SIGKILL the worker when its *parent* exits,
  whatever the worker is doing (even inside C code holding the GIL);
* everywhere: a daemon thread waits on the watched process (a pidfd, woken by the kernel
  when it exits; a 0.1 s poll where pidfds do not exist) and on the parent, and ends the
  worker with ``os._exit`` the moment either is gone.

A sweep's pool workers are children of multiprocessing's forkserver, not of the driver:
the forkserver would only notice the driver's death on its own pipe, then spend ~1 s in
interpreter shutdown before the workers' parent-death signal fires. So the forkserver
exits at once too (``exit_with_starter``, run by its preload import), and each worker also
watches the driver itself.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import select
import signal
import sys
import threading
import time

POLL_S = 0.1  # fallback poll period where pidfds do not exist
STARTER_ENV = "CONTINUUM_SIM_DIE_WITH"  # pid of the process whose direct children must die with it


def _pdeathsig() -> None:
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        pass


def _pidfd(pid: int) -> int | None:
    """A descriptor that becomes readable when ``pid`` exits; None where unsupported. Raises ProcessLookupError if gone."""
    try:
        return os.pidfd_open(pid)
    except (AttributeError, NotImplementedError, PermissionError):
        return None
    except OSError as exc:
        if isinstance(exc, ProcessLookupError):
            raise
        return None


def pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (one owned by another user counts: signal 0 is refused, not lost)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _watch(watched_pid: int, parent_pid: int) -> None:
    pids = {watched_pid, parent_pid}
    try:
        fds = [fd for fd in (_pidfd(pid) for pid in pids) if fd is not None]
    except ProcessLookupError:
        os._exit(1)
    if len(fds) == len(pids):
        while True:
            with contextlib.suppress(InterruptedError):
                if select.select(fds, [], [])[0]:
                    os._exit(1)
    while True:
        time.sleep(POLL_S)
        if not pid_alive(watched_pid) or os.getppid() != parent_pid:
            os._exit(1)


def die_with(watched_pid: int | None = None, kernel: bool = True) -> None:
    """Call in a freshly started worker: exit when ``watched_pid`` (default: the parent) or the parent is gone.

    ``kernel=False`` skips ``PR_SET_PDEATHSIG``, which fires when the parent *thread* that
    started this process ends (for a long-lived server started from any thread, too early).
    """
    parent = os.getppid()
    if kernel:
        _pdeathsig()
    if os.getppid() != parent:  # the parent died before the kernel knew to tell us
        os._exit(1)
    target = parent if watched_pid is None else watched_pid
    threading.Thread(target=_watch, args=(target, parent), daemon=True, name="die-with-parent").start()


def mark_starter() -> None:
    """In a driver: processes it starts that call ``exit_with_starter`` (the forkserver) die with it."""
    os.environ[STARTER_ENV] = str(os.getpid())


def exit_with_starter() -> bool:
    """In a direct child of a ``mark_starter`` process: exit the moment it is gone; True there, False elsewhere."""
    if os.environ.get(STARTER_ENV) != str(os.getppid()):
        return False
    die_with(kernel=False)
    return True
