"""Cable friction in a scenario run: install it on the run's data, record the loss per cable.

The physics lives in ``continuum_sim.plant.friction`` (a passive-force callback acting
inside every ``mj_step``); this observer installs it when the run starts (after the
priming commands), records each cable's anchor-to-motor tension ratio on the recorder's
ticks (the trajectory's ``<arm>_cable_anchor_ratio``) and removes it when the run ends.
With μ = 0 it installs nothing and records ratios of 1.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..model.friction_options import CableFrictionConfig
from ..plant.friction import CableFriction, install_cable_friction
from ..plant.passive import raise_pending
from .simulate import Observer, Simulation


class CableFrictionObserver(Observer):
    """Cable friction for one run; ``every`` must be the recorder's tick interval (same rows)."""

    def __init__(self, config: CableFrictionConfig, every: int) -> None:
        self.config = config
        self.every = max(1, int(every))
        self.handle: CableFriction | None = None
        self.columns: dict[str, np.ndarray] = {}
        self.rows: dict[str, list[np.ndarray]] = {}

    def start(self, sim: Simulation) -> None:
        h = sim.handles
        tendons = np.concatenate([np.asarray(h.cable_tendons[arm], dtype=np.int64) for arm in h.arms])
        # (on the native cable path friction takes that path's routing and reads its pieces)
        self.handle = install_cable_friction(sim.model, sim.data, self.config, tendons)
        index = {int(t): i for i, t in enumerate(self.handle.routing.tendon_ids)}
        self.columns = {arm: np.array([index[int(t)] for t in h.cable_tendons[arm]]) for arm in h.arms}
        self.rows = {arm: [] for arm in h.arms}

    def before_tick(self, sim: Simulation) -> None:
        if sim.tick % self.every or self.handle is None:
            return
        ratio = self.handle.anchor_ratio()
        for arm, cols in self.columns.items():
            self.rows[arm].append(ratio[cols])

    def after_tick(self, sim: Simulation) -> str | None:
        raise_pending()  # a Ctrl-C/SIGTERM that landed inside the passive callback
        if self.handle is not None and self.handle.error is not None:
            if not isinstance(self.handle.error, Exception):  # Ctrl-C/SIGTERM delivered inside the C callback
                raise self.handle.error
            return f"cable friction failed at t = {sim.data.time:.4f} s: {self.handle.error!r}"
        return None

    def close(self, sim: Simulation) -> None:  # noqa: ARG002 - the Observer hook's signature
        if self.handle is not None:
            self.handle.uninstall()

    def arrays(self) -> dict[str, np.ndarray]:
        """``<arm>_cable_anchor_ratio`` (rows, cables) for the trajectory."""
        return {f"{arm}_cable_anchor_ratio": np.array(rows, dtype=float).reshape(len(rows), -1) for arm, rows in self.rows.items()}


def friction_metrics(trajectory: Any, config: Any) -> dict[str, Any]:
    """Friction loss per cable: the anchor/motor tension ratio over the run (1 = no loss).

    ``mean`` per arm and cable (``<arm>/cable_<section>_<c>`` order of the trajectory's
    cable columns), the smallest and largest ratio seen, the mean loss in percent over all
    cables (signed: reeling in loses tension toward the anchor, paying out gains it) and
    the mean |change| in percent (how far friction moves the anchor tension either way).
    """
    arms = trajectory.arms
    means = {arm: [float(x) for x in a.cable_anchor_ratio.mean(axis=0)] for arm, a in arms.items()}
    allr = np.concatenate([a.cable_anchor_ratio for a in arms.values()], axis=1)
    return {
        "mu": float(config.model.cable_friction.mu),
        "anchor_ratio_mean": means,
        "anchor_ratio_min": float(allr.min()) if allr.size else 1.0,
        "anchor_ratio_max": float(allr.max()) if allr.size else 1.0,
        "tension_loss_mean_percent": float(100.0 * (1.0 - allr.mean())) if allr.size else 0.0,
        "tension_change_mean_abs_percent": float(100.0 * np.abs(1.0 - allr).mean()) if allr.size else 0.0,
    }
