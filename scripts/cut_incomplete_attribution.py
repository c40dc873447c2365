"""Why a run ends `cut_incomplete` with every kerf-core column "cut", and what the open loop's 3-D cutting error is.

    python scripts/cut_incomplete_attribution.py [--quick] [--out docs/calibration] [--keep DIR]

Runs the variants one at a time through `run_scenario` (shipped defaults plus a few dotted
overrides) with an extra observer that copies the cutter's 3-D voxel grid at the end of the
planned cut and at the end of the run. For each variant it reports the outcome, the kerf
metrics, and the decisive measurement behind a `cut_incomplete`:

* the kerf-core "cells" (`cells_total` / `cells_remaining`) count a column as cut once the
  cutter removed *one* voxel of it (`FoamGrid.removed_at`); detachment is a 3-D
  face-connectivity test (`foam.held_anchored`): the material under the jaws must lose every
  face path to the clamped edge. So a column touched but not cut through still holds.
* the material left in the planned kerf (full width) when the cut ends: voxels, columns,
  layers (k = 0 bottom … top), and where along the kerf (arc length s from the front edge);
* whether that material is the bridge: clearing the whole kerf band in a copy of the grid
  frees the sample (then the bridge is inside the kerf) or not (it is outside: the cut left
  the planned band);
* the cutter's axial extent (bottom / top of the cutting cylinder vs the plate's faces) and
  its lateral offset where it passed the bridge;
* the 3-D cutting error (`cutting_tip_error_mm`) split into along-path (lead/lag), across-path
  (what `cut_path_deviation_mm` measures) and vertical components, per kerf leg.

Writes <out>/cut_incomplete_attribution.json and .md. --quick: only the open-loop default and
μ = 0.3 open loop. --keep: keep each variant's run folder (else a temporary folder).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from variant_runs import _fmt as _f  # the variant tables' cell format (scripts/variant_runs.py)

from continuum_sim.configio import replace_path
from continuum_sim.model.options import model_geometry
from continuum_sim.plant import foam
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.scenario.runner import run_scenario
from continuum_sim.scenario.simulate import Observer
from continuum_sim.scenario.trajectory import Trajectory
from continuum_sim.toolpath import plan_task

OPEN, CLOSED = {"control.mode": "open"}, {"control.mode": "closed"}
GRAVITY_OFF = {"model.gravity": False}
VARIANTS = [
    ("open, default", OPEN),
    ("open, gravity off", {**OPEN, **GRAVITY_OFF}),
    ("closed, gravity off", {**CLOSED, **GRAVITY_OFF}),
    ("open, μ = 0.25", {**OPEN, "model.cable_friction.mu": 0.25}),
    ("open, μ = 0.3", {**OPEN, "model.cable_friction.mu": 0.3}),
    ("open, μ = 0.4", {**OPEN, "model.cable_friction.mu": 0.4}),
    ("open, μ = 0.5", {**OPEN, "model.cable_friction.mu": 0.5}),
]
QUICK = ("open, default", "open, μ = 0.5")


class GridSnapshots(Observer):
    """Copies of the cutter's voxel grid at the end of the planned cut and at the end of the run."""

    def __init__(self) -> None:
        self.at_cut_end: dict[str, Any] | None = None
        self.at_end: dict[str, Any] | None = None
        self._was_cutting = False

    @staticmethod
    def _snap(sim: Any) -> dict[str, Any]:
        c = sim.cutter
        return {"t": float(sim.data.time), "material": c.grid.material.copy(), "cut": c.grid.cut.copy(),
                "detached": c.detached}

    def after_tick(self, sim: Any) -> str | None:
        cutting = bool(sim.plan.cutting[min(sim.plan_index, len(sim.plan.cutting) - 1)])
        if self._was_cutting and not cutting and self.at_cut_end is None:
            self.at_cut_end = self._snap(sim)
        self._was_cutting = cutting
        return None

    def close(self, sim: Any) -> None:
        self.at_end = self._snap(sim)
        self.grid = sim.cutter.grid
        self.held = sim.cutter._held_flat.copy()
        self.core = sim.cutter._band_columns.copy()


def _polyline_coords(px: np.ndarray, py: np.ndarray, line: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(arc length along ``line`` of the nearest point, signed lateral offset (+: left of travel), leg index)."""
    best = np.full(px.shape, np.inf)
    s_out, off_out, leg_out = np.zeros(px.shape), np.zeros(px.shape), np.zeros(px.shape, int)
    s0 = 0.0
    for k in range(len(line) - 1):
        a, b = line[k, :2], line[k + 1, :2]
        ab = b - a
        length = float(np.linalg.norm(ab))
        u = ab / length
        t = np.clip((px - a[0]) * u[0] + (py - a[1]) * u[1], 0.0, length)
        qx, qy = a[0] + t * u[0], a[1] + t * u[1]
        d = np.hypot(px - qx, py - qy)
        off = -(px - qx) * u[1] + (py - qy) * u[0]
        better = d < best
        best = np.where(better, d, best)
        s_out = np.where(better, s0 + t, s_out)
        off_out = np.where(better, off, off_out)
        leg_out = np.where(better, k, leg_out)
        s0 += length
    return s_out, off_out, leg_out


def _where(s_mm: float, leg_lengths_mm: list[float]) -> str:
    """A name for a place on the kerf (front edge → inner corner → side edge)."""
    total = sum(leg_lengths_mm)
    if s_mm < 3.0:
        return "front-edge end"
    if total - s_mm < 3.0:
        return "side-edge end"
    if abs(s_mm - leg_lengths_mm[0]) < 6.0:
        return "inner corner"
    return "leg 1 (front→corner)" if s_mm < leg_lengths_mm[0] else "leg 2 (corner→side)"


def bridge_analysis(snap: dict[str, Any], obs: GridSnapshots, line: np.ndarray, kerf_width: float,
                    tr: Trajectory) -> dict[str, Any]:
    """The material left in the planned kerf and whether it is what holds the sample."""
    g = obs.grid
    material = snap["material"]
    gx, gy = np.meshgrid(g.centres[0], g.centres[1], indexing="ij")
    s, off, _leg = _polyline_coords(gx, gy, line)
    # Full kerf band: within half a kerf width of the centre line, between the plate's edges.
    band = np.abs(off) <= kerf_width / 2
    leg_mm = [float(np.linalg.norm(line[k + 1, :2] - line[k, :2]) * 1000) for k in range(len(line) - 1)]
    left = material & band[:, :, None]
    n_left = int(left.sum())
    cols = np.argwhere(left.any(axis=2))
    anchored = int(foam.held_anchored(material, obs.held))
    cleared = material.copy()
    cleared[band] = False
    freed_if_band_cleared = int(foam.held_anchored(cleared, obs.held)) == 0
    # Core columns (the metric's "cells"): never touched / touched but not through / through.
    core = obs.core
    touched = snap["cut"].any(axis=2)
    through = ~material.any(axis=2)
    core_stats = {
        "cells": int(core.sum()),
        "never_touched": int((core & ~touched & material.any(axis=2)).sum()),
        "touched_not_through": int((core & touched & material.any(axis=2)).sum()),
        "through": int((core & through).sum()),
    }
    layers = left.sum(axis=(0, 1)).astype(int).tolist()
    out: dict[str, Any] = {
        "t_s": snap["t"], "detached": bool(snap["detached"]), "held_anchored": anchored,
        "kerf_band_voxels_left": n_left, "kerf_band_columns_with_material": len(cols),
        "voxels_left_per_layer_bottom_to_top": layers,
        "sample_freed_if_kerf_band_cleared": bool(freed_if_band_cleared), "core_columns": core_stats,
    }
    if len(cols):
        ss = s[cols[:, 0], cols[:, 1]] * 1000
        oo = off[cols[:, 0], cols[:, 1]] * 1000
        places: dict[str, int] = {}
        for v in ss:
            w = _where(float(v), leg_mm)
            places[w] = places.get(w, 0) + 1
        out["left_columns_where"] = places
        out["left_columns_s_mm"] = [float(ss.min()), float(ss.max())]
        out["left_columns_lateral_mm"] = [float(oo.min()), float(oo.max())]
        # Bridge columns' material: which layers (through-thickness ligament or a skin?)
        out["left_column_layers"] = sorted({int(k) for c in cols for k in np.flatnonzero(material[c[0], c[1]])})
        # Columns the cutter touched but did not cut through: which layers stay, and how low the
        # cutter's bottom face came while its axis was within a cutter radius of them.
        touched = snap["cut"].any(axis=2)
        part = [(i, j) for i, j in cols if touched[i, j]]
        out["partial_columns"] = len(part)
        if part:
            pi = np.array(part)
            out["partial_columns_where"] = {}
            for v in s[pi[:, 0], pi[:, 1]] * 1000:
                w = _where(float(v), leg_mm)
                out["partial_columns_where"][w] = out["partial_columns_where"].get(w, 0) + 1
            out["partial_columns_s_mm"] = [float(s[pi[:, 0], pi[:, 1]].min() * 1000), float(s[pi[:, 0], pi[:, 1]].max() * 1000)]
            out["partial_column_layers_left"] = sorted({int(k) for i, j in part for k in np.flatnonzero(material[i, j])})
            cp = tr.cutting["cutter_pos"]
            axis = tr.arms[tr.tool_arm["grinder"]].tcp_mat[:, :, 2]
            active = tr.cutting["cut_active"].astype(bool)
            half = float(np.linalg.norm(tr.arms[tr.tool_arm["grinder"]].tcp_pos[0] - cp[0]))  # tip face to centre
            bottom = cp[:, 2] - half * axis[:, 2]
            lowest = []
            for i, j in part:
                near = active & (np.hypot(cp[:, 0] - g.centres[0][i], cp[:, 1] - g.centres[1][j]) <= kerf_width / 2)
                if near.any():
                    lowest.append(float(bottom[near].min()))
            out["partial_columns_cutter_bottom_mm"] = {
                "lowest_reached_min": float(np.min(lowest) * 1000) if lowest else None,
                "lowest_reached_max": float(np.max(lowest) * 1000) if lowest else None,
                "bottom_layer_centre": float(g.edges[0] * 1000 + g.h[2] * 500),
                "plate_bottom": float(g.lo[2] * 1000)}
    return out


def error_components(tr: Trajectory, plan: Any) -> dict[str, Any]:
    """The grinder's 3-D tool-centre error over the cut, split along / across the planned path and vertical."""
    arm = tr.tool_arm["grinder"]
    g = tr.arms[arm]
    idx = tr.plan_index.astype(int)
    cut = plan.cutting[idx]
    P = plan.tcp(arm)[:, :3, 3]
    i = idx[cut]
    tangent = P[np.minimum(i + 1, len(P) - 1)] - P[np.maximum(i - 1, 0)]
    tangent[:, 2] = 0.0
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True) + 1e-15
    normal = np.stack([-tangent[:, 1], tangent[:, 0], np.zeros(len(tangent))], axis=1)
    e = g.tcp_pos[cut] - g.tcp_plan[cut, :3, 3]
    along, across, dz = (e * tangent).sum(1), (e * normal).sum(1), e[:, 2]
    plan_xy = g.tcp_plan[cut, :2, 3]
    leg = np.where(np.abs(tangent[:, 1]) > np.abs(tangent[:, 0]), 0, 1)  # leg 1 runs along y, leg 2 along x

    def comp(mask: np.ndarray) -> dict[str, Any]:
        if not mask.any():
            return {}
        ms = lambda v: float(np.sqrt(np.mean(v[mask] ** 2)) * 1000)  # noqa: E731
        return {
            "samples": int(mask.sum()),
            "error_3d_mean_mm": float(np.linalg.norm(e[mask], axis=1).mean() * 1000),
            "along_mean_mm": float(along[mask].mean() * 1000), "along_rms_mm": ms(along),
            "across_mean_mm": float(across[mask].mean() * 1000), "across_rms_mm": ms(across),
            "vertical_mean_mm": float(dz[mask].mean() * 1000), "vertical_rms_mm": ms(dz),
            "x_mean_mm": float(e[mask, 0].mean() * 1000), "y_mean_mm": float(e[mask, 1].mean() * 1000),
        }

    total = float(np.mean(np.sum(e**2, axis=1)))
    out = {"all": comp(np.ones(len(e), bool)), "leg 1 (along y)": comp(leg == 0), "leg 2 (along x)": comp(leg == 1),
           "share_of_mean_square_error": {"along": float(np.mean(along**2) / total),
                                          "across": float(np.mean(across**2) / total),
                                          "vertical": float(np.mean(dz**2) / total)}}
    # The y error over leg 1 in time (is it a lead in time or a position offset that carries into leg 2?)
    t = tr.t[cut]
    first = leg == 0
    if first.any():
        out["leg1_along_start_end_mm"] = [float(along[first][:20].mean() * 1000), float(along[first][-20:].mean() * 1000)]
    second = leg == 1
    if second.any():
        out["leg2_across_start_end_mm"] = [float(across[second][:20].mean() * 1000), float(across[second][-20:].mean() * 1000)]
    out["cut_time_s"] = [float(t[0]), float(t[-1])]
    out["plan_xy_start_mm"] = (plan_xy[0] * 1000).tolist()
    return out


def run_variant(name: str, overrides: dict[str, Any], keep: Path) -> dict[str, Any]:
    config = ScenarioConfig.default()
    for path, value in overrides.items():
        config = replace_path(config, path, value)
    out_dir = keep / name.replace(", ", "_").replace(" ", "_").replace("=", "").replace("μ", "mu")
    obs = GridSnapshots()
    try:
        metrics = run_scenario(config, out_dir, observers=[obs])
    except Exception as exc:  # a divergent variant is a result
        return {"name": name, "overrides": overrides, "error": f"{type(exc).__name__}: {exc}"}
    saved = ScenarioConfig.from_toml(out_dir / "config.toml")
    plan = plan_task(model_geometry(saved.arm, saved.model), saved.layout, saved.plan)
    tr = Trajectory.load(out_dir / "trajectory.npz")
    plate = saved.layout.plate
    line = plate.kerf_polyline()
    row: dict[str, Any] = {
        "name": name, "overrides": overrides,
        "completed": metrics["task"]["completed"], "failure": metrics["task"]["failure"],
        "sample_detached": metrics["sample_detached"], "detach_time_s": metrics["detach_time_s"],
        "cells_total": metrics["cells_total"], "cells_remaining": metrics["cells_remaining"],
        "kerf": metrics.get("cutting", {}).get("kerf"),
        "stall_events": metrics.get("cutting", {}).get("stall_events"),
        "max_cable_tension_n": metrics["max_cable_tension_n"],
        "cut_path_deviation_mm": metrics["cut_path_deviation_mm"],
        "cutting_tip_error_mm": metrics["cutting_tip_error_mm"],
        "cut_end_time_s": None if obs.at_cut_end is None else obs.at_cut_end["t"],
    }
    if obs.at_cut_end is not None:
        row["at_cut_end"] = bridge_analysis(obs.at_cut_end, obs, line, plate.kerf_width, tr)
    assert obs.at_end is not None
    row["at_run_end"] = bridge_analysis(obs.at_end, obs, line, plate.kerf_width, tr)
    row["error_components"] = error_components(tr, plan)
    return row


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = [
        "# cut_incomplete attribution (scripts/cut_incomplete_attribution.py)", "",
        "Kerf-core \"cells\" count a column cut once one voxel of it is removed; detachment needs the held "
        "material to lose every face path to the clamped edge (3-D). Grid state at the end of the planned cut "
        "(after the sample left, where it did). Partial columns: kerf-band columns the cutter touched but did "
        "not cut through; their lowest cutter-bottom height is the lowest the cutting cylinder's bottom face "
        "came within a cutter radius of them (bottom voxel layer centre 530.5 mm, plate 530–540 mm).", "",
        "| variant | outcome | detach (s) | kerf coverage | core cells never cut (metric) / touched, not through | "
        "partial columns: where, layers left | lowest cutter bottom over them (mm) | 3-D cut error mean (mm) | "
        "along / across / vertical rms (mm) | vertical error leg 1 / leg 2 mean (mm) |",
        "|" + "---|" * 10,
    ]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['name']} | error: {r['error']} |" + " |" * 8)
            continue
        a = r.get("at_cut_end") or r["at_run_end"]
        c = a["core_columns"]
        where = (f"{a.get('partial_columns', 0)}: {a.get('partial_columns_where', '')}, k={a.get('partial_column_layers_left', '')}"
                 if a.get("partial_columns") else "0")
        low = a.get("partial_columns_cutter_bottom_mm") or {}
        lowtxt = f"{_f(low.get('lowest_reached_min'), 1)}–{_f(low.get('lowest_reached_max'), 1)}" if low else "–"
        ec = r["error_components"]
        e = ec["all"]
        outcome = "completed" if r["completed"] else f"`{r['failure']}`"
        lines.append(
            f"| {r['name']} | {outcome} | {_f(r['detach_time_s'])} | {_f(r['kerf']['coverage'] if r['kerf'] else None)} | "
            f"{r['cells_remaining']}/{r['cells_total']} / {c['touched_not_through']} | {where} | {lowtxt} | "
            f"{_f(e['error_3d_mean_mm'])} | {_f(e['along_rms_mm'])} / {_f(e['across_rms_mm'])} / {_f(e['vertical_rms_mm'])} | "
            f"{_f(ec['leg 1 (along y)'].get('vertical_mean_mm'))} / {_f(ec['leg 2 (along x)'].get('vertical_mean_mm'))} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="only " + ", ".join(QUICK))
    ap.add_argument("--out", default="docs/calibration")
    ap.add_argument("--keep", default=None, help="keep each variant's run folder under this folder")
    ap.add_argument("--only", nargs="*", default=None, help="variant names to run (default: all)")
    args = ap.parse_args()
    variants = [(n, o) for n, o in VARIANTS if (not args.quick or n in QUICK) and (args.only is None or n in args.only)]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        keep = Path(args.keep) if args.keep else Path(tmp)
        for name, overrides in variants:  # one at a time
            print(f"running {name} …", file=sys.stderr, flush=True)
            row = run_variant(name, overrides, keep)
            rows.append(row)
            print(json.dumps({k: row.get(k) for k in ("name", "completed", "failure", "detach_time_s", "cells_remaining")}),
                  file=sys.stderr, flush=True)
    (out / "cut_incomplete_attribution.json").write_text(json.dumps(rows, indent=1, ensure_ascii=False) + "\n")
    table = markdown(rows)
    (out / "cut_incomplete_attribution.md").write_text(table)
    print(table)


if __name__ == "__main__":
    main()
