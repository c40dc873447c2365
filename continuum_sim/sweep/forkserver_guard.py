"""Imported by the sweep's forkserver (preload): it exits the moment the sweep driver is gone.

Without it, a SIGKILLed driver's forkserver notices on its pipe and then spends ~1 s
shutting its interpreter down (MuJoCo, dm_control, numba loaded) before its children,
the pool workers, get their parent-death signal. A watcher thread ends it at once; if its
own main loop sees the closed pipe first, the interpreter's clean-up (which would freeze
the watcher) is skipped: nothing there needs it. Importing this anywhere else does
nothing (``lifetime.exit_with_starter`` acts only in a direct child of the driver).
"""

import atexit
import os

from ..lifetime import exit_with_starter

if exit_with_starter():
    atexit.register(os._exit, 0)
