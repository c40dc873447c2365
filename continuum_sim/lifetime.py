"""Helper processes never outlive the process that started them (docs/errors.md).

A sweep driver or a video-recording run killed with SIGKILL cannot clean up; its worker
processes must notice on their own. Linux: ``PR_SET_PDEATHSIG`` makes the kernel send
SIGKILL to the worker when its parent exits; everywhere: a daemon thread polls the
watched pid and exits the worker once it is gone or the worker was re-parented.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

POLL_S = 1.0  # a worker whose driver is gone exits within about this long


def _pdeathsig() -> None:
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        pass


def _watch(watched_pid: int, parent_pid: int) -> None:
    while True:
        time.sleep(POLL_S)
        try:
            os.kill(watched_pid, 0)
        except ProcessLookupError:
            os._exit(1)
        except PermissionError:
            pass
        if os.getppid() != parent_pid:
            os._exit(1)


def die_with(watched_pid: int | None = None) -> None:
    """Call in a freshly started worker: exit when ``watched_pid`` (default: the parent) is gone."""
    parent = os.getppid()
    _pdeathsig()
    if os.getppid() != parent:  # the parent died before the kernel knew to tell us
        os._exit(1)
    target = parent if watched_pid is None else watched_pid
    threading.Thread(target=_watch, args=(target, parent), daemon=True, name="die-with-parent").start()
