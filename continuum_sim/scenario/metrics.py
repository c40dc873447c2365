"""Metrics of a run (SPEC §8) computed from its recorded trajectory.

Pure functions of the recorded arrays: ``compute_metrics(trajectory, plan, config)``
needs nothing from the live simulation, so a run folder's ``trajectory.npz`` (with its
``config.toml``, which gives the plan back) is enough to recompute every number in
``metrics.json`` (``continuum-sim metrics RUN_DIR``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from ..toolpath import TaskPlan
    from .config import ScenarioConfig
    from .trajectory import Trajectory

Array = NDArray[np.float64]

# Metrics that depend on the machine, not on the configuration: left out of determinism
# comparisons and of sweep tables.
WALL_CLOCK_METRICS = ("wall_seconds", "wall_real_time_factor", "wall_breakdown_s", "cpu_seconds", "cpu_real_time_factor")


def error_stats(errors_m: Array) -> dict[str, float | None]:
    """mean / RMS / max of an error series, in millimetres (None when empty)."""
    e = np.asarray(errors_m, dtype=float) * 1000.0
    if e.size == 0:
        return {"mean": None, "rms": None, "max": None}
    return {"mean": float(e.mean()), "rms": float(np.sqrt(np.mean(e * e))), "max": float(e.max())}


def _polyline_distance_all(points: Array, polyline: Array) -> Array:
    """Every point against every segment (the definition ``polyline_distance`` reproduces)."""
    best = np.full(len(points), np.inf)
    for a, b in zip(polyline[:-1], polyline[1:]):
        ab = b - a
        t = np.clip(((points - a) @ ab) / max(ab @ ab, 1e-300), 0.0, 1.0)
        d = np.linalg.norm(points - (a + t[:, None] * ab), axis=1)
        best = np.minimum(best, d)
    return best


def polyline_distance(points: Array, polyline: Array) -> Array:
    """Distance of each point (N, 2|3) to a polyline (M, 2|3).

    Bit-identical to ``_polyline_distance_all`` (every segment for every point) at a
    fraction of the cost: a segment is finished only for the points it can be nearest to
    (``_segment_candidates``), the rest of the arithmetic is the same per element, and each
    segment's ``(points - a) @ ab`` is still taken over all points, because BLAS's dot
    product (FMA or not) depends on the array's shape.
    """
    points = np.asarray(points, dtype=float)
    polyline = np.asarray(polyline, dtype=float)
    if len(points) == 0 or len(polyline) < 2:
        return np.full(len(points), np.inf)
    scale = max(float(np.abs(points).max()), float(np.abs(polyline).max()))
    if not (np.isfinite(points).all() and np.isfinite(polyline).all() and 1e-100 < scale < 1e100):
        return _polyline_distance_all(points, polyline)  # NaN propagation, overflow: the definition
    candidates = _segment_candidates(points, polyline, 1e-9 * scale)
    if candidates is None:
        return _polyline_distance_all(points, polyline)  # no pruning to be had (clustered or far points)
    pi, si = candidates
    order = np.argsort(si, kind="stable")
    pi, si = pi[order], si[order]
    segments, starts = np.unique(si, return_index=True)
    stops = np.append(starts[1:], len(si))
    dot = np.empty(len(si))
    squared_length = np.empty(len(segments))
    columns = [np.ascontiguousarray(points[:, j]) for j in range(points.shape[1])]
    for j, (k, start, stop) in enumerate(zip(segments.tolist(), starts.tolist(), stops.tolist())):
        a = polyline[k]
        ab = polyline[k + 1] - a
        squared_length[j] = max(ab @ ab, 1e-300)
        relative = np.empty(points.shape)  # points - a, column by column (a broadcast over 2 is slow)
        for c, column in enumerate(columns):
            np.subtract(column, a[c], out=relative[:, c])
        dot[start:stop] = (relative @ ab)[pi[start:stop]]
    t = np.clip(dot / np.repeat(squared_length, stops - starts), 0.0, 1.0)
    a = polyline[si]
    diff = points[pi] - (a + t[:, None] * (polyline[si + 1] - a))
    sq = diff * diff
    total = sq[:, 0]
    for j in range(1, sq.shape[1]):  # np.linalg.norm's order: ((x² + y²) + z²)
        total = total + sq[:, j]
    best = np.full(len(points), np.inf)
    np.minimum.at(best, pi, np.sqrt(total))
    return best


def _row_norms(x: Array) -> Array:
    """Length of each row of (K, dim), column by column (a reduction over a short axis is slow)."""
    total = x[:, 0] * x[:, 0]
    for j in range(1, x.shape[1]):
        total += x[:, j] * x[:, j]
    return np.sqrt(total)


def _box_distance(points: Array, lo: Array, hi: Array) -> Array:
    """Distance of each point to an axis-aligned box (row by row)."""
    return _row_norms(np.maximum(np.maximum(lo - points, points - hi), 0.0))


def _range_pairs(left: NDArray[np.intp], right: NDArray[np.intp]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """(row, position) of every position in the half-open ranges [left, right) of each row of (N, K) bounds."""
    counts = (right - left).ravel()
    total = int(counts.sum())
    rows = np.repeat(np.repeat(np.arange(left.shape[0]), left.shape[1]), counts)
    first = np.repeat(left.ravel() - (np.cumsum(counts) - counts), counts)
    return rows, first + np.arange(total)


MAX_CANDIDATE_PAIRS = 1 << 20  # above this many (point, segment) pairs the plain loop, in O(N) memory


def _segment_candidates(points: Array, polyline: Array, margin: float) -> tuple[NDArray[np.intp], NDArray[np.intp]] | None:
    """(point, segment) index pairs holding, for every point, each segment whose computed
    distance can be its smallest: the rest cannot change ``polyline_distance``'s minimum.

    Bound: the nearest found vertex v gives an upper bound (the segments ending at v are no
    farther than |p - v|), a segment's bounding box a lower bound; the computed distances
    differ from the exact ones by a few ulps of the coordinates, ``margin`` (1e-9 of them)
    covers that many times over. Found on a grid of cells: a point near the polyline (bound
    under half a cell) against the short segments starting in its own or a neighbouring
    cell; the far points and the long segments against everything. None when that is more
    than ``MAX_CANDIDATE_PAIRS`` pairs to look at.
    """
    n_points, dim = points.shape
    a, b = polyline[:-1], polyline[1:]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    extent = (hi - lo).max(axis=1)
    cell = max(8.0 * float(np.median(extent)), 1e6 * margin)
    half = 0.49 * cell  # a near point and a short segment's start are under one cell apart

    origin = polyline.min(axis=0)
    vertex_cells = np.floor((polyline - origin) / cell).astype(np.int64)
    low, high = vertex_cells.min(axis=0) - 2, vertex_cells.max(axis=0) + 2
    point_cells = np.clip(np.floor((points - origin) / cell), low, high).astype(np.int64)
    strides = np.cumprod(np.append(1, high - low + 1)[:-1])
    offsets = np.array(np.meshgrid(*[[-1, 0, 1]] * dim, indexing="ij")).reshape(dim, -1).T @ strides
    point_keys = (point_cells - low) @ strides

    def near(keys: NDArray[np.int64]) -> tuple[NDArray[np.intp], NDArray[np.intp]] | None:
        """(point, item) pairs of the items whose key is in a point's cell or a neighbour."""
        order = np.argsort(keys, kind="stable")
        query = point_keys[:, None] + offsets[None, :]
        sorted_keys = keys[order]
        left, right = np.searchsorted(sorted_keys, query, "left"), np.searchsorted(sorted_keys, query, "right")
        if int((right - left).sum()) > MAX_CANDIDATE_PAIRS:
            return None
        rows, at = _range_pairs(left, right)
        return rows, order[at]

    vertex_pairs = near((vertex_cells - low) @ strides)
    if vertex_pairs is None:
        return None
    rows, vertex = vertex_pairs
    bound = np.full(n_points, np.inf)
    counts = np.bincount(rows, minlength=n_points)  # rows come sorted
    found = counts > 0
    firsts = (np.cumsum(counts) - counts)[found]
    bound[found] = np.minimum.reduceat(_row_norms(points[rows] - polyline[vertex]), firsts)
    bound += 4.0 * margin
    is_near = bound <= half
    far, near_points = np.flatnonzero(~is_near), np.flatnonzero(is_near)
    short = extent <= half
    long = np.flatnonzero(~short)
    if len(far) * len(a) + len(near_points) * len(long) > MAX_CANDIDATE_PAIRS:
        return None
    for i in far.tolist():  # no vertex close by: the nearest of all
        bound[i] = float(_row_norms(points[i] - polyline).min()) + 4.0 * margin
    segment_pairs = near(np.where(short, (vertex_cells[:-1] - low) @ strides, -1))
    if segment_pairs is None:
        return None
    rows, seg = segment_pairs
    keep = short[seg] & is_near[rows]
    rows, seg = rows[keep], seg[keep]
    all_segments = np.arange(len(a))
    pairs = [
        (rows, seg),
        (np.repeat(near_points, len(long)), np.tile(long, len(near_points))),
        (np.repeat(far, len(a)), np.tile(all_segments, len(far))),
    ]
    pi = np.concatenate([p for p, _ in pairs])
    si = np.concatenate([s for _, s in pairs])
    keep = _box_distance(points[pi], lo[si], hi[si]) <= bound[pi]
    return pi[keep], si[keep]


def axis_angle_deg(axes: Array, reference: Array) -> Array:
    """Angle (deg) between each unit axis (N, 3) and a reference direction (3,)."""
    ref = np.asarray(reference, dtype=float)
    ref = ref / np.linalg.norm(ref)
    cos = np.clip(np.asarray(axes) @ ref, -1.0, 1.0)
    return np.degrees(np.arccos(cos))


def min_backbone_distance(centres_a: Array, radii_a: Array, centres_b: Array, radii_b: Array) -> float:
    """Smallest gap between two arms modelled as chains of spheres (disk centres, radii).

    A sphere of the disk's radius contains the disk, so this is a conservative (never
    larger than the true) clearance between the arms.
    """
    return float(min_backbone_distances(centres_a[None], radii_a, centres_b[None], radii_b)[0])


def min_backbone_distances(centres_a: Array, radii_a: Array, centres_b: Array, radii_b: Array, chunk: int = 256) -> Array:
    """``min_backbone_distance`` of every frame of (N, na, 3) and (N, nb, 3) disk-centre series.

    The centre gaps are summed coordinate by coordinate in ``np.linalg.norm``'s order
    ((x² + y²) + z², the same numbers), without its slow reduction over a length-3 axis
    and with one (chunk, na, nb) buffer reused in place.
    """
    centres_a = np.asarray(centres_a, dtype=float)
    centres_b = np.asarray(centres_b, dtype=float)
    radii = np.asarray(radii_a)[:, None] + np.asarray(radii_b)[None, :]
    out = np.empty(len(centres_a))
    for start in range(0, len(centres_a), chunk):  # bounded memory: chunk × na × nb
        a, b = centres_a[start : start + chunk], centres_b[start : start + chunk]
        total = np.subtract(a[:, :, None, 0], b[:, None, :, 0])
        np.multiply(total, total, out=total)
        gap = np.empty_like(total)
        for j in range(1, a.shape[-1]):
            np.subtract(a[:, :, None, j], b[:, None, :, j], out=gap)
            np.multiply(gap, gap, out=gap)
            np.add(total, gap, out=total)
        np.sqrt(total, out=total)
        np.subtract(total, radii, out=total)
        out[start : start + chunk] = total.reshape(len(a), -1).min(axis=1)
    return out


def per_stage(values: Array, stage: Array, stage_names: tuple[str, ...]) -> dict[str, Any]:
    """error_stats of ``values`` for every stage present in the record."""
    out: dict[str, Any] = {}
    for index, name in enumerate(stage_names):
        mask = stage == index
        if np.any(mask):
            out[name] = error_stats(values[mask])
    out["all"] = error_stats(values)
    return out


SAMPLE_MOVED_M = 1e-3  # the welded sample moving this far on the plate counts as detached early
HELD_DISTANCE_M = 0.05  # a held sample is within this of the gripper's tool centre …
HELD_HEIGHT_M = 0.05  # … and lifted above this height (off the plate's level)
SATURATION_FRACTION = 0.99  # a cable at this fraction of the motors' force rating is saturated

# The named outcomes of a run, first that applies wins (``task_outcome``).
TASK_FAILURES = (
    "diverged",  # the simulation stopped early (non-finite state, MuJoCo warning)
    "partial_run",  # only some stages were run: the task cannot complete
    "detached_early",  # the welded sample moved before the cut freed it (dragged by the gripper)
    "cables_saturated",  # not cut free, and a cable reached the motors' force rating
    "spindle_stalled",  # not cut free, and the spindle stalled under the cutting load
    "cut_incomplete",  # not cut free for any other reason (the cutter missed the kerf)
    "sample_dropped",  # cut free after the cut, not held at the end
)


def task_outcome(metrics: dict[str, Any], all_stages: bool, force_rating: float) -> dict[str, Any]:
    """Whether the task completed and, if not, its first named failure (TASK_FAILURES).

    A variant of a design sweep then records *why* it failed, not only that it did.
    """
    saturated = metrics["max_cable_tension_n"] >= SATURATION_FRACTION * force_rating
    stalls = (metrics.get("cutting") or {}).get("stall_events", 0)
    checks = (
        ("diverged", "diverged" in metrics),
        ("partial_run", not all_stages),
        ("detached_early", metrics["detached_before_cut_complete"]),
        ("cables_saturated", not metrics["sample_detached"] and saturated),
        ("spindle_stalled", not metrics["sample_detached"] and stalls > 0),
        ("cut_incomplete", not metrics["sample_detached"]),
        ("sample_dropped", not metrics["sample_held_at_end"]),
    )
    failure = next((name for name, failed in checks if failed), None)
    return {"completed": failure is None, "failure": failure, "cables_saturated": bool(saturated)}


def compute_metrics(trajectory: Trajectory, plan: TaskPlan, config: ScenarioConfig) -> dict[str, Any]:
    """SPEC §8 metrics of a run, from its trajectory, its plan and its configuration only."""
    from .trajectory import CONTACT_KINDS

    tr = trajectory
    stage = tr.stage.astype(int)
    grinder, gripper = tr.arms[tr.tool_arm["grinder"]], tr.arms[tr.tool_arm["gripper"]]
    out: dict[str, Any] = {"control": config.control.controller or config.control.mode}
    out["tip_error_mm"] = {
        arm: per_stage(np.linalg.norm(a.tcp_pos - a.tcp_plan[:, :3, 3], axis=1), stage, tr.stage_names)
        for arm, a in tr.arms.items()
    }
    cutting = plan.cutting[tr.plan_index.astype(int)]
    grinder_err = np.linalg.norm(grinder.tcp_pos - grinder.tcp_plan[:, :3, 3], axis=1)
    out["cutting_tip_error_mm"] = error_stats(grinder_err[cutting])
    # Deviation across the planned cut, in the plate plane (the kerf's own line plus lead-in/out).
    planned_cut = plan.tcp(tr.tool_arm["grinder"])[plan.cutting][:, :2, 3]
    out["cut_path_deviation_mm"] = error_stats(polyline_distance(grinder.tcp_pos[cutting, :2], planned_cut))
    axis_err = axis_angle_deg(grinder.tcp_mat[cutting, :, 2], np.array([0.0, 0.0, 1.0]))
    out["spindle_axis_error_deg"] = {
        "mean": float(axis_err.mean()) if axis_err.size else None,
        "max": float(axis_err.max()) if axis_err.size else None,
    }
    out["min_arm_distance_m"] = float(tr.arm_distance.min())
    forces = tr.contact_force
    out["max_contact_force_n"] = {kind: float(forces[:, k].max()) for k, kind in enumerate(CONTACT_KINDS)}
    out["arms_touched"] = bool(forces[:, CONTACT_KINDS.index("arm_arm")].max() > 0.0)
    tension = np.concatenate([a.cable_tension for a in tr.arms.values()], axis=1)
    out["max_cable_tension_n"] = float(tension.max())
    from .cable_friction import friction_metrics

    out["cable_friction"] = friction_metrics(tr, config)
    out["min_cable_tension_n"] = float(tension.min())
    if tr.cutting:
        from ..model.cutting import CuttingRecord, cutting_metrics

        plate = config.layout.plate
        out["cutting"] = cutting_metrics(CuttingRecord.from_arrays(tr.cutting), plate.kerf_polyline(), plate.kerf_width)
    out["cells_total"] = tr.n_cells
    out["cells_remaining"] = int(np.count_nonzero(np.isnan(tr.cell_removal_times)))
    out["sample_detached"] = tr.detach_time is not None
    out["detach_time_s"] = tr.detach_time
    moved = np.linalg.norm(tr.sample_rel_pos - tr.sample_rel_pos[0], axis=1) > SAMPLE_MOVED_M
    out["detached_before_cut_complete"] = bool(np.any(moved & tr.sample_welded))
    sample, tcp = tr.sample_pos[-1], gripper.tcp_pos[-1]
    out["sample_held_at_end"] = bool(np.linalg.norm(sample - tcp) < HELD_DISTANCE_M and sample[2] > HELD_HEIGHT_M)
    out["timestep_s"] = float(config.model.timestep)  # the step the run used (model.stable_step may divide it)
    out["stages_run"] = list(tr.stages_run)
    out["sim_seconds"] = float(tr.t[-1])
    out["wall_seconds"] = float(tr.wall_seconds)
    # Simulated seconds per second: of wall time (everything, video included) and of this process's CPU time
    # (time.process_time over plan, build, simulation and metrics; what benchmarks/scenario.py measures).
    out["wall_real_time_factor"] = float(tr.t[-1] / tr.wall_seconds) if tr.wall_seconds > 0 else None
    out["cpu_seconds"] = tr.cpu_seconds
    out["cpu_real_time_factor"] = float(tr.t[-1] / tr.cpu_seconds) if tr.cpu_seconds else None
    out["wall_breakdown_s"] = dict(tr.wall_breakdown_s)
    if tr.failure is not None:
        out["diverged"] = tr.failure
    out["task"] = task_outcome(out, tuple(tr.stages_run) == tuple(tr.stage_names), config.model.cable_max_force)
    return out
