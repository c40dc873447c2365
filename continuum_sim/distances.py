"""Distances between points, polylines, boxes and chains of spheres: the geometry the planner's
checks (``toolpath``) and the run's metrics (``scenario.metrics``) both measure with.

Pure numpy, no model or scenario imports: a low layer (docs/architecture.md).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


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
