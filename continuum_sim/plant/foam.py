"""The foam: a boolean voxel grid over the cuttable plate, and its connectivity.

The plate's rigid geoms (``model/scene.py``) only carry the gripper and the clamp; what the
cutter meets is ``FoamGrid``, the voxels of every part of the plate the cutter can reach
(the whole plate outside the clamped strip, sample included) at ``FoamOptions.voxel_size``,
with the anchor (the clamped edge) at i = 0.

Detachment is a question of face connectivity (``scipy.ndimage.label``'s default
structure): the sample comes free when the material under the gripper's jaws no longer
connects to the anchor face. ``held_anchored`` answers it with a flood fill from the held
material that stops at the anchor face (a connected grid, the usual case, costs a short
walk), and ``free_loose`` removes what lost the anchor. On the default grid (160×150×10,
``python benchmarks/connectivity.py``) a check takes 0.036 ms CPU, a labelling of the whole
grid 1.8 ms (~50×), so the flood is the production path and ``ndimage.label`` its test
oracle (``tests/test_foam.py``: the same verdict and the same freed voxels).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .jit import jit


class FoamGrid:
    """Boolean voxels of the cuttable plate: ``material[i, j, k]`` (x, y, z), anchor at i = 0."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, voxel_size: float) -> None:
        self.lo = np.asarray(lo, float)
        self.hi = np.asarray(hi, float)
        self.shape = tuple(max(1, math.ceil(float(e) / voxel_size - 1e-9)) for e in self.hi - self.lo)
        self.h = (self.hi - self.lo) / np.array(self.shape)
        self.material = np.ones(self.shape, dtype=bool)
        self.cut = np.zeros(self.shape, dtype=bool)  # removed by the cutter (not: left with the sample)
        self.removed_at = np.full(self.shape[:2], np.nan, dtype=np.float32)  # first removal per column (s)
        self.centres = [self.lo[a] + (np.arange(n) + 0.5) * self.h[a] for a, n in enumerate(self.shape)]
        self.edges = self.lo[2] + np.arange(self.shape[2] + 1) * self.h[2]  # z layer edges

    @property
    def voxel_volume(self) -> float:
        return float(np.prod(self.h))

    def reset(self) -> None:
        self.material[...] = True
        self.cut[...] = False
        self.removed_at[...] = np.nan

    def cut_map(self) -> np.ndarray:
        """Fraction of each column's voxels the cutter removed (2-D, x by y): the kerf seen from above."""
        return self.cut.mean(axis=2)


def plate_grid(layout: Any, voxel_size: float) -> FoamGrid:
    """The grid of a task layout's plate outside the clamped strip (the clamp side is the anchor)."""
    plate = layout.plate
    bottom = plate.top_z - plate.thickness
    x0 = plate.corner_x - plate.size[0] + layout.clamp_length
    lo = np.array([x0, plate.corner_y, bottom])
    hi = np.array([plate.corner_x, plate.corner_y + plate.size[1], plate.top_z])
    return FoamGrid(lo, hi, voxel_size)


# ------------------------------------------------------------------ connectivity (numba, compiled on first call)
@jit
def _push(material: np.ndarray, seen: np.ndarray, stack: np.ndarray, top: int, i: int, j: int, k: int) -> int:
    """Put voxel (i, j, k) on the flood's ``stack`` if it is unseen material; the new stack top."""
    if material[i, j, k] and not seen[i, j, k]:
        seen[i, j, k] = True
        stack[top] = (i * material.shape[1] + j) * material.shape[2] + k
        return top + 1
    return top


@jit
def _flood(material: np.ndarray, seen: np.ndarray, stack: np.ndarray, top: int, stop_at_anchor: bool) -> bool:
    """Depth-first flood fill over face neighbours from the ``top`` voxels on ``stack`` (already
    marked in ``seen``), marking what it reaches. With ``stop_at_anchor`` it returns True as
    soon as it reaches the anchor face i = 0; the step towards i = 0 is taken first, so a
    connected grid is proven after few voxels."""
    nx, ny, nz = material.shape
    for t in range(top):
        if stack[t] // (ny * nz) == 0 and stop_at_anchor:
            return True
    while top > 0:
        top -= 1
        v = stack[top]
        k = v % nz
        j = (v // nz) % ny
        i = v // (ny * nz)
        # Pushed last, taken first: towards the anchor.
        if i + 1 < nx:
            top = _push(material, seen, stack, top, i + 1, j, k)
        if k + 1 < nz:
            top = _push(material, seen, stack, top, i, j, k + 1)
        if k > 0:
            top = _push(material, seen, stack, top, i, j, k - 1)
        if j + 1 < ny:
            top = _push(material, seen, stack, top, i, j + 1, k)
        if j > 0:
            top = _push(material, seen, stack, top, i, j - 1, k)
        if i > 0:
            pushed = _push(material, seen, stack, top, i - 1, j, k)
            if stop_at_anchor and i == 1 and pushed > top:
                return True  # reached the anchor face
            top = pushed
    return False


@jit
def held_anchored(material: np.ndarray, held: np.ndarray) -> int:
    """Whether the material in the held columns (flat (i, j) indices ``held``) still connects
    to the anchor face i = 0: 1 yes, 0 no, -1 no material there."""
    nx, ny, nz = material.shape
    seen = np.zeros(material.shape, np.bool_)
    stack = np.empty(nx * ny * nz, np.int64)
    top = 0
    for c in held:
        for k in range(nz):
            top = _push(material, seen, stack, top, c // ny, c % ny, k)
    if top == 0:
        return -1
    return 1 if _flood(material, seen, stack, top, True) else 0


@jit
def free_loose(material: np.ndarray) -> int:
    """Remove the material not connected to the anchor face i = 0 (it left with the sample);
    returns the voxels removed."""
    nx, ny, nz = material.shape
    seen = np.zeros(material.shape, np.bool_)
    stack = np.empty(nx * ny * nz, np.int64)
    top = 0
    for j in range(ny):
        for k in range(nz):
            top = _push(material, seen, stack, top, 0, j, k)
    _flood(material, seen, stack, top, False)
    count = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if material[i, j, k] and not seen[i, j, k]:
                    material[i, j, k] = False
                    count += 1
    return count


@jit
def columns_with_material(material: np.ndarray, columns: np.ndarray) -> int:
    """How many of the voxel columns ``columns`` (flat (i, j) indices) hold material."""
    ny, nz = material.shape[1], material.shape[2]
    count = 0
    for c in columns:
        i, j = c // ny, c % ny
        for k in range(nz):
            if material[i, j, k]:
                count += 1
                break
    return count


