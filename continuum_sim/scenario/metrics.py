"""Metrics of a run (SPEC §8) computed from its recorded time series.

Pure functions of the recorded arrays, so a run folder's ``trajectory.npz`` is enough
to recompute every number in ``metrics.json``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

# Metrics that depend on the machine, not on the configuration: left out of determinism
# comparisons and of sweep tables.
WALL_CLOCK_METRICS = ("wall_seconds", "real_time_factor", "wall_breakdown_s")


def error_stats(errors_m: Array) -> dict[str, float | None]:
    """mean / RMS / max of an error series, in millimetres (None when empty)."""
    e = np.asarray(errors_m, dtype=float) * 1000.0
    if e.size == 0:
        return {"mean": None, "rms": None, "max": None}
    return {"mean": float(e.mean()), "rms": float(np.sqrt(np.mean(e * e))), "max": float(e.max())}


def polyline_distance(points: Array, polyline: Array) -> Array:
    """Distance of each point (N, 2|3) to a polyline (M, 2|3)."""
    points = np.asarray(points, dtype=float)
    best = np.full(len(points), np.inf)
    for a, b in zip(polyline[:-1], polyline[1:]):
        ab = b - a
        t = np.clip(((points - a) @ ab) / max(ab @ ab, 1e-300), 0.0, 1.0)
        d = np.linalg.norm(points - (a + t[:, None] * ab), axis=1)
        best = np.minimum(best, d)
    return best


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
    """``min_backbone_distance`` of every frame of (N, na, 3) and (N, nb, 3) disk-centre series."""
    centres_a = np.asarray(centres_a, dtype=float)
    centres_b = np.asarray(centres_b, dtype=float)
    radii = np.asarray(radii_a)[:, None] + np.asarray(radii_b)[None, :]
    out = np.empty(len(centres_a))
    for start in range(0, len(centres_a), chunk):  # bounded memory: chunk × na × nb × 3
        a, b = centres_a[start : start + chunk], centres_b[start : start + chunk]
        d = np.linalg.norm(a[:, :, None, :] - b[:, None, :, :], axis=-1)
        out[start : start + chunk] = np.min(d - radii, axis=(1, 2))
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
