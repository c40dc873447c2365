"""The foam's connectivity (plant/foam.py's flood fill) against ``scipy.ndimage.label``, its oracle."""

import numpy as np
import pytest
from scipy import ndimage

from continuum_sim.plant import foam


def _labelled(material, held_columns):
    """The oracle: (-1 no held material / 1 anchored / 0 loose, the loose voxels) from a
    labelling of the whole grid (face connectivity, ``ndimage.label``'s default structure)."""
    labels, _ = ndimage.label(material)
    anchored = np.unique(labels[0])
    anchored = anchored[anchored > 0]
    held = labels[held_columns]
    held = held[held > 0]
    loose = (labels > 0) & ~np.isin(labels, anchored)
    if held.size == 0:
        return -1, loose
    return int(np.isin(held, anchored).any()), loose


@pytest.mark.parametrize("fill", [0.3, 0.45, 0.6, 0.9])
def test_flood_fill_equals_labelling_on_random_grids(fill):
    """The flood fill (early exit at the anchor face) against the labelling: the same verdict
    and the same freed voxels, around the percolation threshold and above."""
    rng = np.random.default_rng(int(fill * 100))
    outcomes = set()
    for _ in range(60):
        shape = tuple(int(n) for n in rng.integers(1, 9, size=3))
        material = rng.random(shape) < fill
        held_columns = rng.random(shape[:2]) < 0.2
        held_columns[rng.integers(shape[0]), rng.integers(shape[1])] = True
        verdict, loose = _labelled(material, held_columns)
        assert foam.held_anchored(material, np.flatnonzero(held_columns).astype(np.int64)) == verdict
        outcomes.add(verdict)
        freed = material.copy()
        assert foam.free_loose(freed) == np.count_nonzero(loose)
        assert np.array_equal(freed, material & ~loose)
    assert len(outcomes) >= 2 or fill > 0.8  # (a dense grid is always anchored)


def test_flood_fill_on_a_cut_plate():
    """A slab cut through except a one-voxel bridge: anchored until the bridge goes, then the
    far part is freed; no material under the jaws: -1."""
    material = np.ones((40, 30, 5), bool)
    material[20, :, :] = False
    material[20, 29, 4] = True  # the bridge
    held = np.zeros((40, 30), bool)
    held[35, 10] = True
    flat = np.flatnonzero(held).astype(np.int64)
    assert foam.held_anchored(material, flat) == _labelled(material, held)[0] == 1
    material[20, 29, 4] = False
    assert foam.held_anchored(material, flat) == _labelled(material, held)[0] == 0
    freed = material.copy()
    assert foam.free_loose(freed) == 19 * 30 * 5
    assert np.array_equal(freed, material & ~_labelled(material, held)[1])
    material[:, 10, :] = False
    assert foam.held_anchored(material, flat) == _labelled(material, held)[0] == -1


def test_columns_with_material_counts_columns():
    material = np.zeros((3, 4, 2), bool)
    material[0, 1, 1] = material[2, 3, 0] = material[2, 3, 1] = True
    columns = np.array([1, 11, 5], np.int64)  # (0, 1), (2, 3), (1, 1)
    assert foam.columns_with_material(material, columns) == 2
