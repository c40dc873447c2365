"""numba kernels of ``cutting.FoamCutter``: the voxel work of one physics step, and the connectivity check.

``engage`` (layer weights, the voxels inside the cutter, the engaged depth on the leading
half circle with the recent-centres exclusion, its bin integrals) and ``remove`` (voxel
removal, first-removal times) do what ``FoamCutter``'s numpy path does, in the same
floating-point order, so both paths give bit-identical results
(``tests/test_cutting_native.py``):

* elementwise expressions are written in numpy's operation order (no fast-math, no fused
  multiply-add);
* the products with the layer weights and the bin integrals call BLAS as numpy does
  (``np.dot``: ``ddot`` for one row, ``dgemv`` for several, as numpy's ``matmul``);
* the mean depth is numpy's pairwise sum (``_pairwise_sum``).

``held_anchored`` and ``free_loose`` are the connectivity check (``FoamCutter.check_connectivity``):
a flood fill over face neighbours, as ``scipy.ndimage.label``'s default structure, gives
the same verdict and frees the same voxels as the numpy path's labelling; it starts at the
held material and stops at the anchor face, so a still-connected grid costs a short walk
instead of a labelling of every voxel.

The BLAS numba calls is SciPy's OpenBLAS, numpy's is its own build of the same library;
the equality tests would show if a platform's two builds summed differently.

Lazy like ``friction.kernels``: nothing imports numba until a native cutter is built.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .jit import jit_in_place

_KERNELS: dict[str, Any] = {}


def _index_range(lo: float, h: float, n: int, a: float, b: float) -> tuple[int, int]:
    """``FoamGrid.index_range``: [i0, i1) of the voxels whose centres may lie in [a, b]."""
    i0 = math.floor((a - lo) / h - 0.5)
    i1 = math.ceil((b - lo) / h + 0.5)
    return max(0, i0), min(n, i1)


def _block_sum(a: np.ndarray, start: int, n: int) -> float:
    """numpy's pairwise sum of a block of n <= 128: 8 accumulators, then the rest in order."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[start + i]
        return res
    r0, r1, r2, r3 = a[start], a[start + 1], a[start + 2], a[start + 3]
    r4, r5, r6, r7 = a[start + 4], a[start + 5], a[start + 6], a[start + 7]
    i = 8
    while i < n - n % 8:
        s = start + i
        r0 += a[s]
        r1 += a[s + 1]
        r2 += a[s + 2]
        r3 += a[s + 3]
        r4 += a[s + 4]
        r5 += a[s + 5]
        r6 += a[s + 6]
        r7 += a[s + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[start + i]
        i += 1
    return res


def _pairwise_sum(a: np.ndarray) -> float:
    """numpy's pairwise summation of a contiguous float64 array (what its ``sum``/``mean``
    compute): blocks of up to 128 (``_block_sum``), halves (rounded to 8) added recursively.

    The recursion runs on an explicit stack: numba's cache cannot load a self-recursive
    function (it crashed on the cached copy)."""
    n = a.size
    if n <= 128:
        return _block_sum(a, 0, n)
    depth = 64
    starts = np.empty(depth, np.int64)
    sizes = np.empty(depth, np.int64)
    phase = np.zeros(depth, np.int64)  # 0: left half next, 1: right half next, 2: add them
    left = np.empty(depth)
    starts[0], sizes[0], top, value = 0, n, 0, 0.0
    while top >= 0:
        s, m = starts[top], sizes[top]
        half = m // 2
        half -= half % 8
        if m <= 128:
            value = _block_sum(a, s, m)
            top -= 1
        elif phase[top] == 0:
            phase[top] = 1
            top += 1
            starts[top], sizes[top], phase[top] = s, half, 0
        elif phase[top] == 1:
            left[top] = value
            phase[top] = 2
            top += 1
            starts[top], sizes[top], phase[top] = s + half, m - half, 0
        else:
            value = left[top] + value
            top -= 1
    return value


def _engage(
    material: np.ndarray, xc: np.ndarray, yc: np.ndarray, zc: np.ndarray, edges: np.ndarray, lo: np.ndarray,
    h: np.ndarray, recent: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray, i_cc: np.ndarray, i_cs: np.ndarray,
    i_c: np.ndarray, cx: float, cy: float, z0: float, z1: float, r: float, probe: float, probe2: float,
    ex: float, ey: float, feeding: bool,
) -> tuple[int, float, float, float, float]:
    """(voxels of material inside the cutter, Σ a·I_cc, Σ a·I_cs, Σ a·I_c, mean a) with a the
    engaged depth at the probe angles (the sums only while ``feeding``, else 0)."""
    nx, ny, nz = material.shape
    # Counting only: ``cut`` and ``removed_at`` are never touched, so any arrays of the right rank do.
    n_inside = _inside(material, material, material[:, :, 0], xc, yc, zc, lo, h, cx, cy, z0, z1, r, False, 0.0)
    if not feeding:
        return n_inside, 0.0, 0.0, 0.0, 0.0
    weights = np.empty(nz)
    for k in range(nz):
        v = min(edges[k + 1], z1) - max(edges[k], z0)
        weights[k] = v if v > 0.0 else 0.0
    m = cos_t.size
    depth = np.zeros(m)
    rows = np.empty((m, nz))  # the columns of the probes inside the grid, as float
    where = np.empty(m, np.int64)
    reached = np.zeros(m, np.bool_)
    n_rows = 0
    for p in range(m):
        qx = cx + probe * (ex * cos_t[p] - ey * sin_t[p])
        qy = cy + probe * (ey * cos_t[p] + ex * sin_t[p])
        i = int(math.floor((qx - lo[0]) / h[0]))
        j = int(math.floor((qy - lo[1]) / h[1]))
        if i >= 0 and i < nx and j >= 0 and j < ny:
            for k in range(nz):
                rows[n_rows, k] = 1.0 if material[i, j, k] else 0.0
            where[n_rows] = p
            n_rows += 1
        for q in range(recent.shape[0]):
            ddx = qx - recent[q, 0]
            ddy = qy - recent[q, 1]
            if ddx * ddx + ddy * ddy < probe2:
                reached[p] = True
                break
    # numpy's matmul over the rows inside: one row is a dot product (ddot), several a dgemv.
    if n_rows == 1:
        depth[where[0]] = np.dot(rows[0], weights)
    elif n_rows > 1:
        values = np.dot(np.ascontiguousarray(rows[:n_rows]), weights)
        for n in range(n_rows):
            depth[where[n]] = values[n]
    for p in range(m):
        if reached[p]:
            depth[p] = 0.0
    return (n_inside, np.dot(depth, i_cc), np.dot(depth, i_cs), np.dot(depth, i_c), _pairwise_sum(depth) / m)


def _inside(
    material: np.ndarray, cut: np.ndarray, removed_at: np.ndarray, xc: np.ndarray, yc: np.ndarray, zc: np.ndarray,
    lo: np.ndarray, h: np.ndarray, cx: float, cy: float, z0: float, z1: float, r: float, remove: bool, time: float,
) -> int:
    """The voxels of material inside the cutter: counted, or (``remove``) removed — ``cut``
    marks them and a column's first removal time goes to ``removed_at``. Returns their number."""
    nx, ny, nz = material.shape
    i0, i1 = _index_range(lo[0], h[0], nx, cx - r, cx + r)
    j0, j1 = _index_range(lo[1], h[1], ny, cy - r, cy + r)
    k0, k1 = _index_range(lo[2], h[2], nz, z0, z1)
    rr = r * r
    count = 0
    for i in range(i0, i1):
        dx = xc[i] - cx
        for j in range(j0, j1):
            dy = yc[j] - cy
            if dx * dx + dy * dy <= rr:
                hit = False
                for k in range(k0, k1):
                    if material[i, j, k] and zc[k] >= z0 and zc[k] <= z1:
                        count += 1
                        if remove:
                            material[i, j, k] = False
                            cut[i, j, k] = True
                            hit = True
                if hit and math.isnan(removed_at[i, j]):
                    removed_at[i, j] = time
    return count


def _remove(
    material: np.ndarray, cut: np.ndarray, removed_at: np.ndarray, xc: np.ndarray, yc: np.ndarray, zc: np.ndarray,
    lo: np.ndarray, h: np.ndarray, cx: float, cy: float, z0: float, z1: float, r: float, time: float,
) -> int:
    """Remove the material inside the cutter (``cut`` marks it; a column's first removal time
    goes to ``removed_at``); returns the voxels removed."""
    return _inside(material, cut, removed_at, xc, yc, zc, lo, h, cx, cy, z0, z1, r, True, time)


def _push(material: np.ndarray, seen: np.ndarray, stack: np.ndarray, top: int, i: int, j: int, k: int) -> int:
    """Put voxel (i, j, k) on the flood's ``stack`` if it is unseen material; the new stack top."""
    if material[i, j, k] and not seen[i, j, k]:
        seen[i, j, k] = True
        stack[top] = (i * material.shape[1] + j) * material.shape[2] + k
        return top + 1
    return top


def _flood(material: np.ndarray, seen: np.ndarray, stack: np.ndarray, top: int, stop_at_anchor: bool) -> bool:
    """Depth-first flood fill over face neighbours (``ndimage.label``'s default structure) from
    the ``top`` voxels on ``stack`` (already marked in ``seen``), marking what it reaches. With
    ``stop_at_anchor`` it returns True as soon as it reaches the anchor face i = 0; the step
    towards i = 0 is taken first, so a connected grid is proven after few voxels."""
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


def _held_anchored(material: np.ndarray, held: np.ndarray) -> int:
    """Whether the material in the held columns (flat (i, j) indices ``held``) still connects
    to the anchor face i = 0: 1 yes, 0 no, -1 no material there (as ``FoamCutter``'s labelling)."""
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


def _free_loose(material: np.ndarray) -> int:
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


def _columns_with_material(material: np.ndarray, columns: np.ndarray) -> int:
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


def kernels() -> dict[str, Any]:
    """The compiled kernels ``engage``, ``remove``, ``held_anchored``, ``free_loose`` and
    ``columns_with_material``
    (compiled, or loaded from numba's cache, on first use)."""
    if not _KERNELS:
        jit_in_place(globals(), ("_index_range", "_block_sum", "_pairwise_sum", "_inside", "_engage", "_remove",
                                 "_push", "_flood", "_held_anchored", "_free_loose", "_columns_with_material"))
        _KERNELS.update(engage=_engage, remove=_remove, held_anchored=_held_anchored, free_loose=_free_loose,
                        columns_with_material=_columns_with_material)
    return _KERNELS
