"""``continuum-sim export RUN_DIR --rerun``: a run folder as a Rerun recording (``.rrd``) to scrub in the Rerun viewer.

Built from the run folder alone (``trajectory.npz`` and ``config.toml``; no MuJoCo, no GL),
on one timeline ``sim_time`` (the record ticks, 62.5 Hz):

* ``world/<arm>/backbone`` and ``world/<arm>/disks``: the arms, from the recorded disk centres;
* ``world/<arm>/tool`` and ``world/<arm>/tool_axis``: each tool centre and its axis;
* ``world/<arm>/planned_path`` and ``world/<arm>/measured_path``: the planned and measured
  tool-centre paths (whole, static), ``world/<arm>/measured_so_far`` growing with time;
* ``world/plate`` and ``world/sample``: the foam plate (static box) and the sample's centre;
* ``world/kerf``: the voxel columns the cutter removed (``kerf_map``), each shown from the
  first cut of its kerf-band cell (``cell_removal_times``; columns outside the band's core
  take the time of the nearest band cell), coloured by the removed fraction;
* ``plots/...``: the time series (tool-centre errors, cable tensions, spindle speed,
  cutting force, cells remaining, arm gap, stage).

``rerun-sdk`` is the optional extra ``replay`` (``pip install -e ".[replay]"``); without it
the command says so in one line (exit 2). Why Rerun and not a 3-D HTML page: docs/report.md.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from ..configio import ConfigError

TIMELINE = "sim_time"
ARM_COLOURS = {"left": (214, 39, 40), "right": (31, 119, 180)}
MAX_KERF_UPDATES = 200  # kerf snapshots at most (each holds every column cut so far)


def require_rerun() -> Any:
    """The ``rerun`` module, or a one-line ConfigError naming the extra to install."""
    try:
        import rerun
    except ImportError as exc:
        raise ConfigError("--rerun", f"needs the rerun-sdk package ({exc}); install the extra: pip install -e \".[replay]\" "
                                     "(or pip install rerun-sdk)") from None
    return rerun


def _disk_radii(config: dict[str, Any], n_disks: int) -> np.ndarray:
    sections = (config.get("arm") or {}).get("sections") or [{"disk_diameter": 0.046}]
    diameters = np.array([float(s.get("disk_diameter", 0.046)) for s in sections])
    index = np.minimum(np.arange(n_disks) * len(diameters) // max(n_disks, 1), len(diameters) - 1)
    return 0.5 * diameters[index]


def kerf_columns(cutting: dict[str, np.ndarray], removal_times: np.ndarray, polyline: np.ndarray,
                 kerf_width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centres (K, 3), removed fraction (K,), time each appears (K,)) of the cut voxel columns.

    The band cells of ``cell_removal_times`` are the columns within a quarter kerf width of
    the planned kerf line (``plant.foam``: the kerf's core), in grid order; when the count
    matches, their recorded first-cut times are used and every other cut column takes the
    time of the nearest band cell. Otherwise (a run of an older layout) every column appears
    at the end of the run.
    """
    kerf_map = np.asarray(cutting["kerf_map"], dtype=float)
    lo = np.asarray(cutting["kerf_map_lo"], dtype=float)
    h = np.asarray(cutting["kerf_map_spacing"], dtype=float)
    nx, ny = kerf_map.shape
    gx, gy = np.meshgrid(lo[0] + (np.arange(nx) + 0.5) * h[0], lo[1] + (np.arange(ny) + 0.5) * h[1], indexing="ij")
    band = np.zeros((nx, ny), dtype=bool)
    line = np.asarray(polyline, dtype=float)[:, :2]
    radius = 0.25 * kerf_width
    for a, b in zip(line[:-1], line[1:]):
        ab = b - a
        t = np.clip(((gx - a[0]) * ab[0] + (gy - a[1]) * ab[1]) / float(ab @ ab), 0.0, 1.0)
        band |= (gx - a[0] - t * ab[0]) ** 2 + (gy - a[1] - t * ab[1]) ** 2 <= radius**2
    cut = kerf_map > 0.0
    centres = np.column_stack([gx[cut], gy[cut], np.zeros(int(cut.sum()))])  # z: the caller's (the plate's top)
    times = np.full(int(cut.sum()), np.inf)
    if int(band.sum()) == removal_times.size:
        band_xy = np.column_stack([gx[band], gy[band]])
        band_t = np.asarray(removal_times, dtype=float)
        known = np.isfinite(band_t)
        if known.any():
            d = np.linalg.norm(centres[:, None, :2] - band_xy[None, known], axis=2)
            times = band_t[known][np.argmin(d, axis=1)]
    return centres, kerf_map[cut], times


def export_rerun(run_dir: Path, out: Path) -> dict[str, Any]:
    """Write the recording of ``run_dir`` to ``out``; returns a summary (entities, frames, bytes)."""
    rr = require_rerun()
    from ..model.names import arm_cable_names
    from ..scenario.trajectory import Trajectory

    run_dir = Path(run_dir)
    for name in ("config.toml", "trajectory.npz"):
        if not (run_dir / name).is_file():
            raise ConfigError("RUN_DIR", f"{run_dir} has no {name} (not a run folder, or the run did not finish)")
    try:
        tr = Trajectory.load(run_dir / "trajectory.npz")
    except Exception as exc:  # noqa: BLE001 - zip, missing keys, truncation: all mean unreadable
        raise ConfigError("RUN_DIR", f"{run_dir}/trajectory.npz is not a readable trajectory ({type(exc).__name__}: {exc})") from None
    config = tomllib.loads((run_dir / "config.toml").read_text())
    from ..scenario.config import ScenarioConfig

    plate = ScenarioConfig.from_toml(run_dir / "config.toml").layout.plate
    rec = rr.RecordingStream(application_id="continuum_sim", recording_id=f"run:{run_dir.resolve().name}")
    rec.save(str(out))
    t = np.asarray(tr.t, dtype=float)
    n = t.size
    times = [rr.TimeColumn(TIMELINE, duration=t)]
    entities: list[str] = []

    def columns(path: str, archetype_columns: Any) -> None:
        rec.send_columns(path, indexes=times, columns=archetype_columns)
        entities.append(path)

    def static(path: str, value: Any) -> None:
        rec.log(path, value, static=True)
        entities.append(path)

    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    centre = np.asarray(plate.centre, dtype=float)
    static("world/plate", rr.Boxes3D(centers=[centre], half_sizes=[0.5 * np.array(plate.size)], colors=[(243, 234, 208, 90)],
                                     fill_mode="solid", labels=["foam plate"]))
    for arm, a in tr.arms.items():
        colour = ARM_COLOURS.get(arm, (90, 90, 90))
        disks = np.asarray(a.disk_pos, dtype=float)
        n_disks = disks.shape[1]
        radii = np.tile(_disk_radii(config, n_disks), n)
        columns(f"world/{arm}/disks", rr.Points3D.columns(positions=disks.reshape(-1, 3), radii=radii).partition([n_disks] * n))
        columns(f"world/{arm}/backbone", rr.LineStrips3D.columns(strips=list(disks), colors=[colour] * n))
        columns(f"world/{arm}/tool", rr.Points3D.columns(positions=a.tcp_pos, radii=np.full(n, 0.004), colors=[colour] * n))
        axis = np.asarray(a.tcp_mat, dtype=float)[:, :, 2] * 0.05
        columns(f"world/{arm}/tool_axis", rr.Arrows3D.columns(origins=a.tcp_pos, vectors=axis, colors=[colour] * n))
        planned = np.asarray(a.tcp_plan, dtype=float)[:, :3, 3]
        static(f"world/{arm}/planned_path", rr.LineStrips3D([planned], colors=[(40, 160, 40)], labels=[f"{arm} planned"]))
        static(f"world/{arm}/measured_path", rr.LineStrips3D([a.tcp_pos], colors=[(*colour, 120)], labels=[f"{arm} measured"]))
        stride = max(1, n // 400)  # the growing path: ~400 updates
        for k in range(stride, n + stride, stride):
            end = min(k, n)
            rec.set_time(TIMELINE, duration=float(t[end - 1]))
            rec.log(f"world/{arm}/measured_so_far", rr.LineStrips3D([a.tcp_pos[:end]], colors=[colour]))
        entities.append(f"world/{arm}/measured_so_far")
        error_mm = np.linalg.norm(a.tcp_pos - planned, axis=1) * 1000.0
        columns(f"plots/tool_centre_error_mm/{arm}", rr.Scalars.columns(scalars=error_mm))
        names = arm_cable_names(arm, a.cable_tension.shape[1] // 3)  # "<arm>/cable_<section>_<k>", the model's names
        for c, name in enumerate(names):
            columns(f"plots/tension_n/{name}", rr.Scalars.columns(scalars=a.cable_tension[:, c]))
    columns("world/sample", rr.Points3D.columns(positions=tr.sample_pos, radii=np.full(n, 0.006), colors=[(208, 128, 80)] * n))
    columns("plots/spindle_speed_rad_s", rr.Scalars.columns(scalars=tr.spindle_speed))
    columns("plots/cells_remaining", rr.Scalars.columns(scalars=tr.cells_remaining.astype(float)))
    columns("plots/arm_gap_mm", rr.Scalars.columns(scalars=tr.arm_distance * 1000.0))
    columns("plots/stage", rr.Scalars.columns(scalars=tr.stage.astype(float)))
    n_kerf, kerf_timed = 0, False
    if tr.cutting:
        force = np.asarray(tr.cutting["cut_force"], dtype=float)
        columns("plots/cutting_force_n", rr.Scalars.columns(scalars=np.linalg.norm(force[:, :2], axis=1)))
        xyz, fraction, appear = kerf_columns(tr.cutting, tr.cell_removal_times, plate.kerf_polyline(), plate.kerf_width)
        xyz[:, 2] = plate.top_z + 0.0005  # just above the top face
        n_kerf, kerf_timed = len(xyz), bool(np.isfinite(appear).any())
        colours = np.column_stack([np.full(n_kerf, 120), 60 + 100 * (1 - fraction), np.full(n_kerf, 20)]).astype(np.uint8)
        appear = np.where(np.isfinite(appear), appear, t[-1])
        order = np.argsort(appear, kind="stable")
        steps = np.unique(np.searchsorted(t, appear[order]).clip(0, n - 1))
        if steps.size > MAX_KERF_UPDATES:
            steps = steps[np.linspace(0, steps.size - 1, MAX_KERF_UPDATES).round().astype(int)]
        half = 0.5 * np.asarray(tr.cutting["kerf_map_spacing"], dtype=float)
        for step in steps:
            shown = order[appear[order] <= t[step]]
            rec.set_time(TIMELINE, duration=float(t[step]))
            rec.log("world/kerf", rr.Boxes3D(centers=xyz[shown], half_sizes=np.tile([half[0], half[1], 0.0005], (shown.size, 1)),
                                             colors=colours[shown], fill_mode="solid"))
        entities.append("world/kerf")
    rec.flush()
    rec.disconnect()
    return {"path": str(out), "frames": n, "entities": sorted(set(entities)), "kerf_columns": n_kerf, "kerf_timed": kerf_timed,
            "bytes": Path(out).stat().st_size if Path(out).exists() else 0}
