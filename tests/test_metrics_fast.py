"""The per-coordinate ``min_backbone_distances`` gives exactly the numbers of its plain
formulation (written out here as the reference)."""

import numpy as np
import pytest

from continuum_sim.scenario import metrics as met


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
