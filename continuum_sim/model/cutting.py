"""Runtime cutting: the spinning cutter removes kerf cells; the sample comes free at the end.

The scene (``scene.py``) fills the kerf with small static box cells ``kerf_000`` … in the
plate body and welds the sample body to the plate with ``sample_weld``. ``KerfCutter``
is called once per control step: every cell that has a contact with the cutter while the
spindle runs loses its collisions (``geom_contype``/``geom_conaffinity`` = 0) and its
visibility (alpha 0); when the last cell goes, the weld is deactivated
(``data.eq_active``) and the sample is a free body. The cutter's detection shell
(geom ``gap``, no force) reports contacts before they exert force, so a moving cutter
removes a cell before pressing on it. With the spindle off the cells are ordinary foam.

This mutates ``model`` (collision masks, colours); ``reset()`` restores them, together
with a ``mj_resetData``.
"""

from __future__ import annotations

import mujoco
import numpy as np

from .scene import KERF_PREFIX, SAMPLE_BODY, SAMPLE_WELD
from .tools import CUTTER_GEOM, GRINDER, SPINDLE_JOINT


class KerfCutter:
    """Removes kerf cells touched by the spinning cutter; releases the sample weld last."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, arm: str = "left", min_speed: float = 10.0) -> None:
        """``min_speed`` (rad/s): spindle speed counted as running when ``update`` is not told."""
        self.model = model
        self.data = data
        self.cutter = _id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{arm}/{GRINDER}/{CUTTER_GEOM}")
        spindle = _id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{arm}/{GRINDER}/{SPINDLE_JOINT}")
        self._spindle_dof = int(model.jnt_dofadr[spindle])
        self.weld = _id(model, mujoco.mjtObj.mjOBJ_EQUALITY, SAMPLE_WELD)
        self.sample_body = _id(model, mujoco.mjtObj.mjOBJ_BODY, SAMPLE_BODY)
        names = [model.geom(i).name for i in range(model.ngeom)]
        self.cells = np.array(sorted(i for i, n in enumerate(names) if n.startswith(KERF_PREFIX)), dtype=int)
        if self.cells.size == 0:
            raise ValueError(f"model has no kerf cells (geoms named {KERF_PREFIX}*)")
        self.min_speed = float(min_speed)
        self._contype0 = model.geom_contype[self.cells].copy()
        self._conaffinity0 = model.geom_conaffinity[self.cells].copy()
        self._alpha0 = model.geom_rgba[self.cells, 3].copy()
        self._cell_of_geom = np.full(model.ngeom + 1, -1, dtype=int)  # geom id -> cell index (-1: not a cell; last: none)
        self._cell_of_geom[self.cells] = np.arange(self.cells.size)
        self.reset(reset_data=False)

    # ------------------------------------------------------------------ state
    def reset(self, reset_data: bool = False) -> None:
        """Restore every cell and the weld (and ``mj_resetData`` when asked)."""
        if reset_data:
            mujoco.mj_resetData(self.model, self.data)
        self.model.geom_contype[self.cells] = self._contype0
        self.model.geom_conaffinity[self.cells] = self._conaffinity0
        self.model.geom_rgba[self.cells, 3] = self._alpha0
        self.data.eq_active[self.weld] = 1
        self.removal_time = np.full(self.cells.size, np.nan)
        self.detach_time: float | None = None

    @property
    def n_cells(self) -> int:
        return int(self.cells.size)

    @property
    def removed(self) -> np.ndarray:
        """Boolean mask over cells (in ``kerf_000`` … order)."""
        return ~np.isnan(self.removal_time)

    @property
    def cells_remaining(self) -> int:
        return int(np.count_nonzero(np.isnan(self.removal_time)))

    @property
    def detached(self) -> bool:
        return self.detach_time is not None

    @property
    def spindle_speed(self) -> float:
        return float(self.data.qvel[self._spindle_dof])

    # ------------------------------------------------------------------ step
    def touching_cells(self) -> np.ndarray:
        """Indices (into ``cells``) of remaining cells in contact with the cutter now."""
        n = self.data.ncon
        if n == 0:
            return np.empty(0, dtype=int)
        geom = self.data.contact.geom[:n]
        # The other geom of each cutter contact (-1, mapped to "not a cell", otherwise).
        other = np.where(geom[:, 0] == self.cutter, geom[:, 1], np.where(geom[:, 1] == self.cutter, geom[:, 0], -1))
        hits = self._cell_of_geom[other]
        hits = hits[hits >= 0]
        return np.unique(hits[np.isnan(self.removal_time[hits])])

    def update(self, spindle_on: bool | None = None) -> list[int]:
        """Remove cells the running cutter touches; release the weld after the last one.

        ``spindle_on`` None reads the spindle's measured speed (``|ω| ≥ min_speed``).
        Returns the indices of the cells removed now. Call after ``mj_step`` (the
        contacts are those of the last step).
        """
        if spindle_on is None:
            spindle_on = abs(self.spindle_speed) >= self.min_speed
        removed: list[int] = []
        if spindle_on and not self.detached:
            for k in self.touching_cells():
                g = self.cells[k]
                self.model.geom_contype[g] = 0
                self.model.geom_conaffinity[g] = 0
                self.model.geom_rgba[g, 3] = 0.0
                self.removal_time[k] = self.data.time
                removed.append(int(k))
        if not self.detached and self.cells_remaining == 0:
            self.data.eq_active[self.weld] = 0
            self.detach_time = float(self.data.time)
        return removed

    def status(self) -> dict[str, object]:
        """A JSON-ready summary for run reports."""
        return {
            "cells_total": self.n_cells,
            "cells_remaining": self.cells_remaining,
            "detached": self.detached,
            "detach_time_s": self.detach_time,
            "cell_removal_times_s": [None if np.isnan(t) else float(t) for t in self.removal_time],
        }


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise ValueError(f"model has no {kind.name.removeprefix('mjOBJ_').lower()} named {name!r}")
    return int(i)
