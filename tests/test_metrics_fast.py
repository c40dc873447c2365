"""The pruned ``polyline_distance`` and the per-coordinate ``min_backbone_distances`` give
exactly the numbers of their plain formulations (written out here as the reference)."""

import numpy as np
import pytest

from continuum_sim import distances as met


def reference_polyline_distance(points, polyline):
    """The original: every segment for every point."""
    points = np.asarray(points, dtype=float)
    best = np.full(len(points), np.inf)
    for a, b in zip(polyline[:-1], polyline[1:]):
        ab = b - a
        t = np.clip(((points - a) @ ab) / max(ab @ ab, 1e-300), 0.0, 1.0)
        d = np.linalg.norm(points - (a + t[:, None] * ab), axis=1)
        best = np.minimum(best, d)
    return best


def reference_min_backbone_distances(centres_a, radii_a, centres_b, radii_b, chunk=256):
    """The original: np.linalg.norm over the coordinate axis of (chunk, na, nb, 3) differences."""
    centres_a = np.asarray(centres_a, dtype=float)
    centres_b = np.asarray(centres_b, dtype=float)
    radii = np.asarray(radii_a)[:, None] + np.asarray(radii_b)[None, :]
    out = np.empty(len(centres_a))
    for start in range(0, len(centres_a), chunk):
        a, b = centres_a[start : start + chunk], centres_b[start : start + chunk]
        d = np.linalg.norm(a[:, :, None, :] - b[:, None, :, :], axis=-1)
        out[start : start + chunk] = np.min(d - radii, axis=(1, 2))
    return out


def _path(rng, n, dim, step=5e-5, offset=0.05):
    """A cut-like polyline: a random walk of small steps around 0.05 m (around the origin,
    the dot product's last bit reaches the distances: BLAS's order matters there)."""
    return offset + np.cumsum(rng.normal(scale=step, size=(n, dim)), axis=0)


def _same(points, polyline):
    np.testing.assert_array_equal(met.polyline_distance(points, polyline), reference_polyline_distance(points, polyline))


@pytest.mark.parametrize("offset", [0.05, 0.0])
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", range(6))
def test_polyline_distance_equals_the_all_segments_loop(dim, seed, offset):
    rng = np.random.default_rng(seed)
    line = _path(rng, int(rng.integers(2, 800)), dim, offset=offset)
    along = line[rng.integers(0, len(line), 600)]
    near = along + rng.normal(scale=float(rng.choice([1e-6, 2e-5, 2e-4])), size=along.shape)
    far = line.mean(axis=0) + rng.normal(scale=0.05, size=(40, dim))  # off the grid of cells: the fallback
    _same(np.concatenate([near, far]), line)


@pytest.mark.parametrize("dim", [2, 3])
def test_polyline_distance_degenerate_and_long_segments(dim):
    rng = np.random.default_rng(11)
    line = _path(rng, 300, dim)
    line = np.concatenate([line[:100], line[99:100], line[99:100], line[100:], line[-1:] + 0.03, line[-1:] - 0.02])
    points = np.concatenate([line + rng.normal(scale=3e-5, size=line.shape), line[[0, 99, 100, -1]]])  # on vertices too
    _same(points, line)
    _same(points, line[[0, 0]])  # one zero-length segment
    _same(points, line[[0, 0, 0, 5]])
    _same(points, np.concatenate([line[:1], line[:1] + 1e-30, line[1:3]]))  # den below 1e-300: clamped


@pytest.mark.parametrize("dim", [2, 3])
def test_polyline_distance_edge_inputs(dim):
    rng = np.random.default_rng(3)
    line = _path(rng, 50, dim)
    _same(line[7:8] + 1e-5, line)  # a single point
    _same(line[:3] + 1e-5, line[:2])  # a single segment
    assert met.polyline_distance(np.zeros((0, dim)), line).shape == (0,)
    _same(np.zeros((0, dim)), line)
    _same(line[:4], line[:1])  # no segment: inf
    np.testing.assert_array_equal(met.polyline_distance(line[:4], line[:1]), np.full(4, np.inf))
    _same(np.zeros((3, dim)), np.zeros((4, dim)))  # all zero: the plain loop
    points = line[:5] + 1e-5
    points[2, 0] = np.nan
    _same(points, line)  # NaN propagates as in the loop
    wide = np.concatenate([line + 1e-5, np.zeros((len(line), 1))], axis=1)[:, :dim]  # a strided view, as compute_metrics passes
    assert not wide.flags.c_contiguous
    _same(wide, line)


@pytest.mark.parametrize("n, chunk", [(300, 64), (1, 256), (257, 256), (0, 256), (100, 7)])
def test_min_backbone_distances_equals_the_norm_formulation(n, chunk):
    rng = np.random.default_rng(n + chunk)
    a, b = rng.normal(size=(n, 7, 3)), rng.normal(size=(n, 5, 3)) * rng.choice([1e-3, 1.0, 1e3], size=(n, 5, 3))
    ra, rb = rng.uniform(0.0, 0.2, 7), rng.uniform(0.0, 0.2, 5)
    new = met.min_backbone_distances(a, ra, b, rb, chunk=chunk)
    np.testing.assert_array_equal(new, reference_min_backbone_distances(a, ra, b, rb, chunk=chunk))
    if n > 1:
        a[1, 3, 2] = np.nan
        new = met.min_backbone_distances(a, ra, b, rb, chunk=chunk)
        np.testing.assert_array_equal(new, reference_min_backbone_distances(a, ra, b, rb, chunk=chunk))
        assert np.isnan(new[1])


def test_polyline_distance_without_pruning_is_the_loop(monkeypatch):
    """Clustered vertices or a pair budget exceeded: the plain loop, the same numbers."""
    rng = np.random.default_rng(8)
    line = _path(rng, 200, 2, offset=0.0)
    clustered = np.concatenate([line[:50], np.repeat(line[50:51], 3000, axis=0), line[51:]])  # median length 0
    points = clustered[rng.integers(0, len(clustered), 700)] + rng.normal(scale=1e-5, size=(700, 2))
    _same(points, clustered)
    scale = max(np.abs(points).max(), np.abs(clustered).max())
    assert met._segment_candidates(points, clustered, 1e-9 * scale) is None
    points = line + rng.normal(scale=1e-5, size=line.shape)
    monkeypatch.setattr(met, "MAX_CANDIDATE_PAIRS", 10)
    assert met._segment_candidates(points, line, 1e-9 * np.abs(line).max()) is None
    _same(points, line)


def test_cutting_record_rows_become_the_arrays_np_stack_gave():
    """``CuttingObserver.record`` builds its series with np.array: the rows it records (NumPy and
    Python scalars, bools, small arrays) give np.stack's dtype, shape and values."""
    from types import SimpleNamespace

    from continuum_sim.plant.cut_record import CuttingObserver

    rng = np.random.default_rng(4)
    observer = CuttingObserver.__new__(CuttingObserver)
    observer.rows = {
        "vector": [rng.normal(size=3) for _ in range(50)],
        "numpy_float": [np.float64(x) for x in rng.normal(size=50)],
        "python_float": [float(x) for x in rng.normal(size=50)],
        "bool": [bool(x) for x in rng.integers(0, 2, 50)],
        "mixed_bool": [np.bool_(True), False, True, np.bool_(False)],
        "empty": [],
    }
    grid = SimpleNamespace(cut_map=lambda: np.zeros((2, 2)), lo=np.zeros(3), h=np.ones(3))
    observer.cutter = SimpleNamespace(grid=grid)
    observer.spindle = SimpleNamespace(events=[])
    series = observer.record().series
    for key, rows in observer.rows.items():
        expected = np.stack(rows) if rows else np.zeros((0,))
        assert series[key].dtype == expected.dtype and series[key].shape == expected.shape, key
        np.testing.assert_array_equal(series[key], expected)
