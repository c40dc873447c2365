"""Per-arm control (SPEC §7): planned shape → cable lengths → motor position loops.

* ``config``: ``ControlConfig``, the settings (light: loading a scenario imports it);
* ``arm``: ``ArmController``, one arm's set-points each control tick (open or closed loop);
* ``kernels``: the control tick compiled by numba, its only implementation.

``ArmController`` is imported from ``continuum_sim.control.arm`` (it loads numba), so that
importing this package for the configuration stays light.
"""

from __future__ import annotations

from .config import ControlConfig

__all__ = ["ControlConfig"]
