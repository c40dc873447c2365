"""Compile the passive callback's kernels in a second process while a cold first run starts.

Why: a fresh install's first ``continuum-sim run`` compiles every numba kernel once into the
disk cache (~30 s of CPU, all in the main process, one after the other), while the machine's
second core sits idle: the video's render workers wait for frames that come only once the
physics runs. The cable-friction and native-cable kernels behind the compiled passive callback
(``native_callback.build``, ~9 s) are the last the run needs (when the tick loop starts, after
the cutter's and the controller's kernels), so a second process can compile them meanwhile and
leave them in the same disk cache; the run then loads them. A run whose cache is warm starts
nothing. Nothing but numba's cache files is written (numba writes each entry whole), the
results do not depend on which process compiled a kernel, and a run that gets there first
simply compiles the kernel itself.

    python -m continuum_sim.model.warm      # what the background process runs
"""

from __future__ import annotations

import glob
import os
import subprocess
import sys
from typing import Any

CALLBACK_KERNEL = "native_callback._run_friction"  # the largest of them (~8 s cold)


def _cache_roots() -> list[str]:
    """Where numba keeps this package's kernels: ``NUMBA_CACHE_DIR`` or the modules' ``__pycache__``."""
    here = os.path.dirname(os.path.abspath(__file__))
    custom = os.environ.get("NUMBA_CACHE_DIR")
    return [custom] if custom else [os.path.join(here, "__pycache__")]


def callback_cached() -> bool:
    """True when the compiled passive callback's kernels are in numba's disk cache."""
    pattern = f"{CALLBACK_KERNEL}-*.nbi"
    return any(glob.glob(os.path.join(root, "**", pattern), recursive=True) for root in _cache_roots())


def start_background_warmup() -> subprocess.Popen[bytes] | None:
    """Start ``python -m continuum_sim.model.warm`` when the callback's kernels are not cached
    (None: cached, or switched off with ``CONTINUUM_SIM_NO_WARMUP=1``). The process is left to
    finish on its own; its output is discarded."""
    if os.environ.get("CONTINUUM_SIM_NO_WARMUP", "") not in ("", "0") or callback_cached():
        return None
    try:
        return subprocess.Popen(
            [sys.executable, "-m", "continuum_sim.model.warm"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            env={**os.environ, "CONTINUUM_SIM_NO_WARMUP": "1"},
        )
    except OSError:
        return None  # no second process: the run compiles everything itself, as before


def compile_callback_kernels() -> Any:
    """Install cable friction on a native-cable data of the default scene: compiles (or loads)
    the native-cable and friction kernels and the compiled callback, with the argument types a
    run uses. Returns the callback (for tests)."""
    from ..scenario.config import ScenarioConfig
    from ..scenario.runner import build_run_model, with_stable_step
    from . import cable_path, friction

    config = with_stable_step(ScenarioConfig.default())
    _, model, _ = build_run_model(config)
    data = cable_path.make_data(model)
    cables = cable_path.native_cables(model)
    handle = friction.install_cable_friction(model, data, config.model.cable_friction,
                                             kernel=None if cables is None else cables.data_kernel(data))
    built = friction._COMPILED[0] if friction._COMPILED else None
    handle.uninstall()
    cable_path.release_data(data)
    return built


if __name__ == "__main__":  # pragma: no cover - the background process
    compile_callback_kernels()
