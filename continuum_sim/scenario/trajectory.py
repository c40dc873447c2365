"""The typed record of one run: everything ``compute_metrics`` and the plots need.

Saved as ``trajectory.npz`` in the run folder: one flat array per series (per-arm series
as ``<arm>_<field>``, e.g. ``left_tcp_pos``), plus ``stage_names`` and a JSON ``meta``
entry (tool pairing, contact kinds, cell removal times, detach time, stages run, failure).
``Trajectory.load(path)`` restores exactly what ``save`` wrote, so ``continuum-sim metrics
RUN_DIR`` recomputes ``metrics.json`` from the folder alone.

The file depends on the configuration only: two identical runs write byte-identical
files. Wall-clock figures (machine-dependent) live in ``metrics.json``'s wall keys alone
(``metrics.WALL_CLOCK_METRICS``), and the zip entries carry a fixed date (``np.savez``
stamps each with the current time).
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..configio import atomic_write_bytes

Array = NDArray[np.float64]

CONTACT_KINDS = ("cutter", "gripper", "arm_arm", "arm_world")  # columns of ``contact_force``


@dataclass(frozen=True)
class ArmTrajectory:
    """One arm's series, one row per record tick (N rows)."""

    q_plan: Array  # (N, 6) planned PCC configuration (θ, φ per section)
    q_cmd: Array  # (N, 6) commanded configuration (the controller's bending command; NaN if it gave none)
    tcp_plan: Array  # (N, 4, 4) planned tool-centre pose
    tcp_pos: Array  # (N, 3) simulated tool-centre position
    tcp_mat: Array  # (N, 3, 3) simulated tool frame
    cable_length: Array  # (N, C) cable path lengths (m)
    cable_tension: Array  # (N, C) cable tensions (N, ≥ 0)
    cable_anchor_ratio: Array  # (N, C) anchor / motor tension (capstan loss in the holes; 1 = none)
    cable_common_mode: Array  # (N, sections) tension keeping's common-mode shortening (m; NaN if none)
    disk_pos: Array  # (N, disks, 3) disk centres


@dataclass(frozen=True)
class Trajectory:
    """A run's recorded series (N rows, one per record tick) and its end-of-run facts."""

    t: Array  # (N,) s
    stage: NDArray[np.int64]  # (N,) index into stage_names
    plan_index: NDArray[np.int64]  # (N,) plan sample
    sample_pos: Array  # (N, 3) world
    sample_rel_pos: Array  # (N, 3) sample position in the plate's frame (relative to the plate body)
    sample_welded: NDArray[np.bool_]  # (N,) the weld holding the sample to the plate is active
    cells_remaining: NDArray[np.int64]  # (N,)
    spindle_speed: Array  # (N,) rad/s
    contact_force: Array  # (N, 4) summed normal force per CONTACT_KINDS entry (N)
    arm_distance: Array  # (N,) smallest gap between the arms' disk spheres (m)
    arms: dict[str, ArmTrajectory]
    stage_names: tuple[str, ...]
    tool_arm: dict[str, str]  # tool -> arm
    cell_removal_times: Array  # (cells,) s; NaN where a cell is still there
    detach_time: float | None  # s when the sample came free; None if it did not
    stages_run: tuple[str, ...]
    failure: str | None  # why the simulation stopped early (divergence), None if it ran to the end
    wall_breakdown_s: dict[str, float]  # where the wall time went (machine-dependent; not saved: {} when loaded)
    wall_seconds: float | None  # not saved (metrics.json has it): None when loaded
    # The cutter's record (plant.cut_record.CuttingRecord.arrays(): cut_* series, kerf_map, ...);
    # empty for runs saved before the foam cutter.
    cutting: dict[str, np.ndarray] = field(default_factory=dict)
    cpu_seconds: float | None = None  # process CPU time of the run (time.process_time); None for runs saved before it

    _ARRAYS = ("t", "stage", "plan_index", "sample_pos", "sample_rel_pos", "sample_welded", "cells_remaining",
               "spindle_speed", "contact_force", "arm_distance")

    @property
    def n_cells(self) -> int:
        return int(self.cell_removal_times.size)

    def series(self) -> dict[str, np.ndarray]:
        """Every series as one flat dict (per-arm keys ``<arm>_<field>``), as saved."""
        out: dict[str, np.ndarray] = {name: getattr(self, name) for name in self._ARRAYS}
        for arm, record in self.arms.items():
            for f in fields(ArmTrajectory):
                out[f"{arm}_{f.name}"] = getattr(record, f.name)
        return out

    def _meta(self) -> dict[str, Any]:
        return {
            "arms": list(self.arms),
            "tool_arm": self.tool_arm,
            "contact_kinds": list(CONTACT_KINDS),
            "cell_removal_times_s": [None if np.isnan(x) else float(x) for x in self.cell_removal_times],
            "detach_time_s": self.detach_time,
            "stages_run": list(self.stages_run),
            "failure": self.failure,
        }

    def to_bytes(self) -> bytes:
        arrays: dict[str, Any] = {**self.series(), **self.cutting, "stage_names": np.array(self.stage_names),
                                   "meta": np.array(json.dumps(self._meta()))}
        return npz_bytes(arrays)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write ``trajectory.npz`` (atomically)."""
        atomic_write_bytes(path, self.to_bytes())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Trajectory:
        """Read what ``save`` wrote."""
        with np.load(path, allow_pickle=False) as npz:
            data = {key: npz[key] for key in npz.files}
        meta = json.loads(str(data.pop("meta")))
        arms = {
            arm: ArmTrajectory(**{f.name: _arm_series(data, arm, f.name) for f in fields(ArmTrajectory)})
            for arm in meta["arms"]
        }
        removal = np.array([np.nan if x is None else x for x in meta["cell_removal_times_s"]], dtype=float)
        return cls(
            **{name: data[name] for name in cls._ARRAYS},
            arms=arms,
            stage_names=tuple(str(s) for s in data["stage_names"]),
            tool_arm=dict(meta["tool_arm"]),
            cell_removal_times=removal,
            detach_time=meta["detach_time_s"],
            stages_run=tuple(meta["stages_run"]),
            failure=meta["failure"],
            wall_breakdown_s=dict(meta.get("wall_breakdown_s", {})),  # files written before they moved out
            wall_seconds=meta.get("wall_seconds"),
            cutting=_cutting_arrays(data),
            cpu_seconds=meta.get("cpu_seconds"),
        )


ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # the zip format's earliest date: entries say nothing about when they were written


def npz_bytes(arrays: dict[str, Any]) -> bytes:
    """``np.savez_compressed``'s file, except that equal arrays give equal bytes (fixed entry dates).

    Same layout as numpy writes (one deflated ``<key>.npy`` per array, ``np.lib.format``
    headers), so ``np.load`` reads it; no pickled objects.
    """
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED, allowZip64=True) as archive:
        for key, value in arrays.items():
            info = zipfile.ZipInfo(f"{key}.npy", date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            with archive.open(info, "w", force_zip64=True) as entry:
                np.lib.format.write_array(entry, np.asanyarray(value), allow_pickle=False)
    return buffer.getvalue()


def _arm_series(data: dict[str, np.ndarray], arm: str, name: str) -> np.ndarray:
    """One saved per-arm series; runs saved before cable friction existed had no loss (ratio 1)."""
    key = f"{arm}_{name}"
    if key not in data and name == "cable_anchor_ratio":
        return np.ones_like(data[f"{arm}_cable_tension"])
    return data[key]


def _cutting_arrays(data: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The cutter's record among the saved arrays (none in runs saved before the foam cutter)."""
    from ..plant.cut_record import CUTTING_ARRAYS

    return {key: data[key] for key in CUTTING_ARRAYS if key in data}
