"""What the cutter did in a run: the tick-loop observer, its record, and the metrics of the cut.

``CuttingObserver`` runs the spindle drive's loop and the cutter before every physics step,
the connectivity check after each tick, and one record row every ``every`` ticks;
``CuttingRecord`` is what it saves (``trajectory.npz``); ``cutting_metrics`` and
``kerf_profile`` measure the force, the spindle and the kerf as cut from that record alone.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

RECORD_FIELDS = (
    "cut_force",  # (N, 3) mean force on the cutter over the tick before the record, N
    "cut_feed_force",  # (N,) against the feed, N
    "cut_normal_force",  # (N,) across the feed, N
    "cut_torque",  # (N,) cutting torque on the spindle, N·m
    "cut_power",  # (N,) W
    "cut_mrr",  # (N,) material removal rate, m³/s
    "cut_depth",  # (N,) mean engaged depth, m
    "cut_chip",  # (N,) feed per revolution, m
    "cut_active",  # (N,) the cutter removed material during the tick
    "cut_blocked",  # (N,) a non-cutting cutter was pressed into material
    "cut_removed_volume",  # (N,) cumulative, m³
    "cutter_pos",  # (N, 3) cutter centre, world
    "spindle_reference",  # (N,) commanded speed, rad/s
    "cut_spindle_speed",  # (N,) measured spindle speed, rad/s
    "spindle_stalled",  # (N,) the drive tripped on a stall
)

CUTTING_ARRAYS = (*RECORD_FIELDS, "kerf_map", "kerf_map_lo", "kerf_map_spacing", "spindle_stall_times")


@dataclass(frozen=True)
class CuttingRecord:
    """What the cutter did in one run: per-record series and the cut kerf (SI units).

    Saved into ``trajectory.npz`` by ``arrays()`` (keys as named, plus ``kerf_map``,
    ``kerf_map_lo``, ``kerf_map_spacing``, ``spindle_stall_times``) and restored by
    ``from_arrays``; ``cutting_metrics`` needs nothing else.
    """

    series: dict[str, np.ndarray]
    kerf_map: np.ndarray  # (nx, ny) fraction of each voxel column the cutter removed
    kerf_map_lo: np.ndarray  # (3,) grid corner (x, y, z), m
    kerf_map_spacing: np.ndarray  # (3,) voxel size, m
    spindle_stall_times: np.ndarray  # (events,) s

    def arrays(self) -> dict[str, np.ndarray]:
        return {**self.series, "kerf_map": self.kerf_map, "kerf_map_lo": self.kerf_map_lo,
                "kerf_map_spacing": self.kerf_map_spacing, "spindle_stall_times": self.spindle_stall_times}

    @classmethod
    def from_arrays(cls, data: dict[str, np.ndarray]) -> CuttingRecord:
        return cls({k: np.asarray(data[k]) for k in RECORD_FIELDS}, np.asarray(data["kerf_map"]),
                   np.asarray(data["kerf_map_lo"]), np.asarray(data["kerf_map_spacing"]),
                   np.asarray(data["spindle_stall_times"]))


_N_MEANS = 10  # the sums the observer averages per tick (``cutter_kernels.SUMS_MEANS``)


class CuttingObserver:
    """The tick-loop hooks of ``scenario.simulate`` (duck-typed ``Observer``): the spindle
    drive's PI loop and the cutter's step before every physics step (set-point from
    ``sim.commands``), the connectivity check after each tick, one record row every ``every`` ticks.

    The spindle drive is the run's (``sim.actuate.spindle``, the motor layer's) where there is
    one, else a new one on this model."""

    def __init__(self, sim: Any, layout: Any, scene: Any, every: int = 1) -> None:
        from .cutter import foam_cutter
        from .cutter_kernels import SUMS, SUMS_MEANS
        from .spindle import SpindleDrive

        arm = sim.handles.tool_arm["grinder"] if hasattr(sim.handles, "tool_arm") else "left"
        spindle = getattr(sim.actuate, "spindle", None)
        self.spindle = spindle if isinstance(spindle, SpindleDrive) else SpindleDrive(sim.model, scene.tools, arm)
        self.cutter = foam_cutter(sim.model, sim.data, layout, scene, self.spindle, arm=arm)
        self.every = max(1, int(every))
        self.rows: dict[str, list[Any]] = {k: [] for k in RECORD_FIELDS}
        self._row_lists = [self.rows[k] for k in RECORD_FIELDS]
        self.sums = np.zeros(1, SUMS)  # over the tick's steps, added to by ``FoamCutter.tick``
        self._sums = self.sums.view(np.float64)  # (the same, as one vector)
        assert SUMS_MEANS == _N_MEANS and self._sums.size == _N_MEANS + 3
        self._reference = 0.0
        self._xpos = sim.data.geom_xpos[self.cutter.cutter]
        self._opt = sim.model.opt

    def start(self, sim: Any) -> None:
        """Nothing to prepare: the cutter was built uncut."""

    def before_tick(self, sim: Any) -> None:
        sums = self._sums
        if sim.tick % self.every == 0:
            n = max(sums[-1], 1.0)
            mean = sums[:_N_MEANS] / n
            c = self.cutter
            # In RECORD_FIELDS order (the SUMS fields' order); the one array that aliases MuJoCo's state copied.
            values = (
                mean[0:3], mean[3], mean[4], mean[5], mean[6], mean[7], mean[8], mean[9], sums[_N_MEANS] != 0.0,
                sums[_N_MEANS + 1] != 0.0,
                c.removed_volume, self._xpos.copy(), self._reference, c.spindle_speed, self.spindle.stalled,
            )
            for rows, value in zip(self._row_lists, values, strict=True):
                rows.append(value)
        sums[:] = 0.0

    def before_physics_step(self, sim: Any) -> None:
        commands = getattr(sim, "commands", None)
        self._reference = reference = float(getattr(commands, "spindle_speed", 0.0) or 0.0)
        self.spindle.step(sim.data, reference, self._opt.timestep)
        self.cutter.tick(self.sums)

    def after_physics_step(self, sim: Any) -> None:
        """Nothing per step after MuJoCo's: removal happens before it."""

    def after_tick(self, _sim: Any) -> str | None:
        self.cutter.after_step()
        return None

    def close(self, sim: Any) -> None:
        """Nothing to release."""

    def record(self) -> CuttingRecord:
        """The run's ``CuttingRecord`` (call after the run)."""
        g = self.cutter.grid
        # np.array, not np.stack: the same arrays (dtype, shape, values: tests/test_metrics_fast.py),
        # without stack's one asanyarray per row.
        series = {k: np.array(v) if v else np.zeros((0,)) for k, v in self.rows.items()}
        stalls = np.array([t for t, e, _ in self.spindle.events if e == "stall"], dtype=float)
        return CuttingRecord(series, g.cut_map().astype(np.float32), g.lo.copy(), g.h.copy(), stalls)


def cutting_metrics(record: CuttingRecord, kerf_polyline: np.ndarray, kerf_width: float) -> dict[str, Any]:
    """Cutting force, spindle, stall, removal and the kerf as cut (a pure function of the record).

    ``kerf_polyline`` is the planned cut centre line (layout); the kerf is measured from the
    cut itself (``kerf_profile`` on ``kerf_map``): its centre's deviation from the plan and
    its width.
    """
    s = record.series
    active = s["cut_active"].astype(bool)
    force = np.linalg.norm(s["cut_force"][:, :2], axis=1) if len(active) else np.zeros(0)

    def stats(x: np.ndarray) -> dict[str, float | None]:
        return {"mean": float(x.mean()) if x.size else None, "max": float(x.max()) if x.size else None}

    out: dict[str, Any] = {
        "force_n": stats(force[active]),
        "feed_force_n": stats(s["cut_feed_force"][active]),
        "normal_force_n": stats(np.abs(s["cut_normal_force"][active])),
        "torque_nm": stats(s["cut_torque"][active]),
        "power_w": stats(s["cut_power"][active]),
        "removed_volume_m3": float(s["cut_removed_volume"][-1]) if len(active) else 0.0,
        "stall_events": len(record.spindle_stall_times),
        "stall_times_s": [float(t) for t in record.spindle_stall_times],
        "blocked": bool(s["cut_blocked"].any()) if len(active) else False,
    }
    speed = s["cut_spindle_speed"]
    if active.any():
        ref = s["spindle_reference"][active]
        out["spindle_speed_drop_pct"] = {
            "mean": float(np.mean((ref - speed[active]) / ref) * 100), "max": float(np.max((ref - speed[active]) / ref) * 100)}
    else:
        out["spindle_speed_drop_pct"] = {"mean": None, "max": None}
    lo, h = record.kerf_map_lo, record.kerf_map_spacing
    stations, centres, widths = kerf_profile(record.kerf_map > 0.5, lo, h, np.asarray(kerf_polyline)[:, :2],
                                             step=float(h[:2].min()), search=1.5 * kerf_width)
    cut = ~np.isnan(widths)
    dev = np.linalg.norm(centres[cut] - stations[cut], axis=1) * 1000 if cut.any() else np.zeros(0)
    out["kerf"] = {
        "coverage": float(cut.mean()) if cut.size else 0.0,  # fraction of the planned kerf where a cut was found
        "width_mm": {"mean": float(widths[cut].mean() * 1000) if cut.any() else None,
                     "min": float(widths[cut].min() * 1000) if cut.any() else None},
        "centre_deviation_mm": {"mean": float(dev.mean()) if dev.size else None, "max": float(dev.max()) if dev.size else None},
    }
    return out


def kerf_profile(
    removed: np.ndarray, lo: np.ndarray, spacing: np.ndarray, polyline: np.ndarray, step: float, search: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kerf as cut, measured from a column map (``FoamGrid.cut_map() > 0.5``).

    At stations every ``step`` along each leg of the planned ``polyline`` (x, y), scan the
    map across the leg within ±``search``; the run of removed columns nearest the planned
    line gives the kerf's edges. Returns (stations (n, 2) on the plan, cut centres (n, 2),
    widths (n,)); NaN where nothing was cut there. Stations within ``search`` of an inner
    vertex are left out (there the scan line runs along the other leg's kerf). The cut
    centres are the "real toolpath" measured from the cut itself (the paper's Fig. 16b);
    their resolution is the voxel (a column is cut when its centre is inside the cutter).
    """
    removed = np.asarray(removed, bool)
    lo, spacing = np.asarray(lo, float)[:2], np.asarray(spacing, float)[:2]
    fine = float(min(spacing)) / 4
    offsets = np.arange(-search, search + fine / 2, fine)
    stations, centres, widths = [], [], []
    pts = np.asarray(polyline, float)[:, :2]
    for a, b in itertools.pairwise(pts):
        length = float(np.linalg.norm(b - a))
        if length <= 0:
            continue
        u = (b - a) / length
        n = np.array([-u[1], u[0]])
        for s in np.arange(step / 2, length, step):
            p = a + s * u
            if any(float(np.linalg.norm(p - v)) < search for v in pts[1:-1]):
                continue  # near an inner corner the scan would run along the other leg's kerf
            line = p[None, :] + offsets[:, None] * n[None, :]
            ij = np.floor((line - lo) / spacing).astype(int)
            ok = (ij[:, 0] >= 0) & (ij[:, 0] < removed.shape[0]) & (ij[:, 1] >= 0) & (ij[:, 1] < removed.shape[1])
            cut = np.zeros(len(offsets), bool)
            cut[ok] = removed[ij[ok, 0], ij[ok, 1]]
            stations.append(p)
            if not cut.any():
                centres.append(np.full(2, np.nan))
                widths.append(np.nan)
                continue
            # Runs of removed samples; the one whose centre lies nearest the planned line.
            edges = np.flatnonzero(np.diff(np.concatenate([[0], cut.astype(int), [0]])))
            runs = edges.reshape(-1, 2)
            mids = np.array([(offsets[r0] + offsets[r1 - 1]) / 2 for r0, r1 in runs])
            r0, r1 = runs[int(np.argmin(np.abs(mids)))]
            lo_off, hi_off = offsets[r0] - fine / 2, offsets[r1 - 1] + fine / 2
            centres.append(p + n * (lo_off + hi_off) / 2)
            widths.append(hi_off - lo_off)
    return np.array(stations).reshape(-1, 2), np.array(centres).reshape(-1, 2), np.array(widths)
