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

``step`` is all of ``FoamCutter.step`` after the spindle's set-point in one call (measured
on the default run: the cutter's per-step hook 0.40 -> 0.27 s CPU): it reads and writes
MuJoCo's buffers through addresses, calls ``mj_jac`` and ``mj_solveM`` through their
addresses (int64 arguments, never baked in, so numba's cache keeps it), reproduces numpy's
BLAS products (gemm, gemv, dot) and CPython's ``math.hypot`` (``_hypot``: libm's differs).

``tick`` is what the observer's per-step hook runs (``FoamCutter.tick``): the spindle's PI
loop (``_spindle``, ``tools.SpindleLoop.control`` on a state array the SpindleLoop object
views), ``step``, the removed volume and the observer's sums, in one call; Python only
appends a stall event or takes the block-spring step (``TICK_*`` flags).

The BLAS numba calls is SciPy's OpenBLAS, numpy's is its own build of the same library;
the equality tests would show if a platform's two builds summed differently.

Lazy like ``friction.kernels``: nothing imports numba until a native cutter is built.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..plant.jit import jit_in_place

_KERNELS: dict[str, Any] = {}
# Bound by ``_bind_intrinsics`` (numba objects, made when the kernels are first compiled).
_carray: Any = None
_f64: Any = None
_call_jac: Any = None
_call_solve: Any = None


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


# ------------------------------------------------------------------ the fused step
# Slots of the fused step's float array ``fv`` (constants set once, state in and out, outputs).
F_DT, F_OMEGA, F_TIME, F_ZMID, F_HALF, F_R, F_PROBE, F_PROBE2 = 0, 1, 2, 3, 4, 5, 6, 7
F_MIN_SPEED, F_U, F_RADIAL, F_STALLED, F_INERTIA, F_TORQUE_APPLIED = 8, 9, 10, 11, 12, 13
F_BOX = 14  # lo0, lo1, lo2, hi0, hi1, hi2
F_APPLIED = 20  # the wrench added to xfrc_applied the step before (6)
F_OUT = 26  # fx, fy, feed_force, normal_force, torque, mrr, power, depth, chip, feed_speed, cutting
F_KIND = F_OUT + 11
# ``_tick``'s slots: the spindle loop's options (kv, ki, max torque, stall fraction, stall
# time, max speed), its state (``SpindleLoop.state`` is a view of these four), the voxel
# volume, the cutter's removed volume, "material was removed since the last connectivity
# look", "the CutState is in F_OUT.. (not built yet)", "the block spring's contact ended"
# and the last outcome.
F_SP_OPT = F_OUT + 12
F_SP = F_SP_OPT + 6
F_VOXEL, F_REMOVED, F_DIRTY, F_LAZY, F_UNBLOCK, F_OUTCOME = range(F_SP + 4, F_SP + 10)
N_F = F_SP + 10
# The observer's sums (``tick``'s ``acc``): the CutState's force (3), feed force, normal
# force, torque, power, mrr, depth, chip (as ``CuttingObserver`` adds them), then
# "removed something", "blocked", the steps.
A_ACTIVE, A_BLOCKED, A_STEPS = 10, 11, 12
N_A = 13
# Slots of the int array ``iv``.
I_RI, I_NULL, I_BODY, I_NV, I_M, I_D, I_JAC, I_SOLVE, I_NPROBE, I_TWO = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9
# Addresses (each a contiguous float64 buffer): MuJoCo's rows, the work arrays, the constants.
(I_XPOS, I_XMAT, I_CVEL, I_COM, I_XIPOS, I_XFRC, I_QFRC, I_QACC, I_JACBUF, I_MINV, I_POINT,
 I_XC, I_YC, I_ZC, I_EDGES, I_LO, I_H, I_COS, I_SIN, I_ICC, I_ICS, I_IC) = range(10, 32)
I_QVEL, I_CTRL = 32, 33  # the spindle's qvel and ctrl entries
N_I = 34
# Outcomes of ``step``.
STEP_FAR, STEP_CUT, STEP_PYTHON = 0, 1, 2
# Flags ``tick`` returns (0: done).
TICK_STALL, TICK_PYTHON = 1, 2


def _pmax(a: float, b: float) -> float:
    """Python's ``max(a, b)`` on floats (the first unless the second is greater: signed zeros kept)."""
    return b if b > a else a


def _pmin(a: float, b: float) -> float:
    """Python's ``min(a, b)`` on floats."""
    return b if b < a else a


def _two_product(x: float, y: float) -> tuple[float, float]:
    """x·y and its exact rounding error (Dekker's product with Veltkamp splitting; CPython's
    ``dl_mul`` gets the same pair from an fma)."""
    z = x * y
    c = 134217729.0  # 2^27 + 1
    t = c * x
    xh = t - (t - x)
    xl = x - xh
    t = c * y
    yh = t - (t - y)
    yl = y - yh
    zz = ((xh * yh - z) + xh * yl + xl * yh) + xl * yl
    return z, zz


def _hypot(x: float, y: float) -> float:
    """CPython's ``math.hypot(x, y)`` (``vector_norm``: correctly rounded; libm's ``hypot``,
    which numba calls, differs in the last bit now and then)."""
    a, b = abs(x), abs(y)
    if math.isinf(a) or math.isinf(b):
        return math.inf
    if math.isnan(a) or math.isnan(b):
        return math.nan
    mx = b if b > a else a
    if mx == 0.0:
        return mx
    outer = 1.0
    _, max_e = math.frexp(mx)
    if max_e < -1023:
        dbl_min = 2.2250738585072014e-308
        a /= dbl_min
        b /= dbl_min
        mx = mx / dbl_min
        outer = dbl_min
        _, max_e = math.frexp(mx)
    scale = math.ldexp(1.0, -max_e)
    csum, frac1, frac2 = 1.0, 0.0, 0.0
    for v in (a, b):
        v *= scale
        hi, lo = _two_product(v, v)
        s = csum + hi
        frac2 += (csum - s) + hi
        csum = s
        frac1 += lo
    h = math.sqrt(csum - 1.0 + (frac1 + frac2))
    hi, lo = _two_product(-h, h)
    s = csum + hi
    frac2 += (csum - s) + hi
    csum = s
    frac1 += lo
    v = csum - 1.0 + (frac1 + frac2)
    h += v / (2.0 * h)
    return outer * (h / scale)


def _step(material: np.ndarray, cut: np.ndarray, removed_at: np.ndarray, recent: np.ndarray, fv: np.ndarray,
          iv: np.ndarray) -> tuple[int, int]:
    """``FoamCutter.step`` after the spindle's set-point, in one call (the same floating-point
    operations in the same order): the cutter's axis point, the near test, the feed velocity,
    ``engage``, the cutting force with the implicit feed (``mj_jac`` and ``mj_solveM`` called
    by address, the BLAS products as numpy's), ``remove``, the wrench and the spindle load.

    Returns (outcome, voxels removed): ``STEP_FAR`` (no material near) or ``STEP_CUT`` (done;
    the state in ``fv[F_OUT:]``, ``F_KIND`` 0 nothing happened, 1 the feeding state, 2 removal
    only), or ``STEP_PYTHON`` when material is inside a cutter that does not cut (the block
    spring: rare, left to the Python path); then nothing was changed."""
    nv, mp = iv[I_NV], iv[I_NPROBE]
    dt, omega = fv[F_DT], fv[F_OMEGA]
    pos = _carray(_f64(iv[I_XPOS]), 3)
    mat = _carray(_f64(iv[I_XMAT]), 9)
    px_, py_, pz_ = pos[0], pos[1], pos[2]
    ax, ay, az = mat[2], mat[5], mat[8]
    z_mid = fv[F_ZMID]
    along = (z_mid - pz_) / az if abs(az) > 0.5 else 0.0
    cx, cy = px_ + along * ax, py_ + along * ay
    half = fv[F_HALF]
    z0 = pz_ - half * abs(az)
    z1 = pz_ + half * abs(az)
    r, probe = fv[F_R], fv[F_PROBE]
    lo0, lo1, lo2 = fv[F_BOX], fv[F_BOX + 1], fv[F_BOX + 2]
    hi0, hi1, hi2 = fv[F_BOX + 3], fv[F_BOX + 4], fv[F_BOX + 5]
    near = cx + probe > lo0 and cx - probe < hi0 and cy + probe > lo1 and cy - probe < hi1 and z1 > lo2 and z0 < hi2
    for q in range(F_OUT, F_KIND + 1):
        fv[q] = 0.0
    fx = fy = 0.0
    torque = 0.0
    n_inside = 0
    outcome = STEP_FAR
    if near:
        w = _carray(_f64(iv[I_CVEL]), 6)
        o = _carray(_f64(iv[I_COM]), 3)
        rx, ry, rz = px_ - o[0], py_ - o[1], pz_ - o[2]
        vx = w[3] + w[1] * rz - w[2] * ry
        vy = w[4] + w[2] * rx - w[0] * rz
        xc, yc, zc = _carray(_f64(iv[I_XC]), material.shape[0]), _carray(_f64(iv[I_YC]), material.shape[1]), \
            _carray(_f64(iv[I_ZC]), material.shape[2])
        lo, h = _carray(_f64(iv[I_LO]), 3), _carray(_f64(iv[I_H]), 3)
        cutting = abs(omega) >= fv[F_MIN_SPEED] and fv[F_STALLED] == 0.0
        if not cutting and _inside(material, material, material[:, :, 0], xc, yc, zc, lo, h, cx, cy, z0, z1, r,
                                   False, 0.0):
            return STEP_PYTHON, 0  # (counting only: nothing changed)
        outcome = STEP_CUT
        speed = _hypot(vx, vy)
        feeding = cutting and speed > 1e-6
        ex, ey = (vx / speed, vy / speed) if feeding else (0.0, 0.0)
        recent[iv[I_RI], 0] = cx
        recent[iv[I_RI], 1] = cy
        n_inside, d_cc, d_cs, d_c, mean_depth = _engage(
            material, xc, yc, zc, _carray(_f64(iv[I_EDGES]), material.shape[2] + 1), lo, h, recent,
            _carray(_f64(iv[I_COS]), mp), _carray(_f64(iv[I_SIN]), mp), _carray(_f64(iv[I_ICC]), mp),
            _carray(_f64(iv[I_ICS]), mp), _carray(_f64(iv[I_IC]), mp), cx, cy, z0, z1, r, probe, fv[F_PROBE2],
            ex, ey, feeding)
        if feeding:
            sgn = 1.0 if omega > 0 else -1.0
            k_t = fv[F_U]
            k_r = k_t * fv[F_RADIAL]
            a = (k_r * d_cc - sgn * k_t * d_cs) / abs(omega)
            bb = (k_r * d_cs + sgn * k_t * d_cc) / abs(omega)
            feed = _implicit_feed(fv, iv, nv, vx, vy, ex, ey, a, bb, dt, cx, cy)
            fx = -feed * (a * ex - bb * ey)
            fy = -feed * (a * ey + bb * ex)
            c = feed / abs(omega)
            area = r * d_c
            torque = c * k_t * area
            fv[F_OUT] = fx
            fv[F_OUT + 1] = fy
            fv[F_OUT + 2] = -(fx * ex + fy * ey)
            fv[F_OUT + 3] = -fx * ey + fy * ex
            fv[F_OUT + 4] = torque
            fv[F_OUT + 5] = feed * area
            fv[F_OUT + 6] = torque * abs(omega)
            fv[F_OUT + 7] = mean_depth
            fv[F_OUT + 8] = 2 * math.pi * c
            fv[F_OUT + 9] = speed
            fv[F_OUT + 10] = 1.0 if area > 0.0 else 0.0
            fv[F_KIND] = 1.0
        if n_inside and cutting:
            _inside(material, cut, removed_at, xc, yc, zc, lo, h, cx, cy, z0, z1, r, True, fv[F_TIME])
            if fv[F_KIND] == 0.0:
                fv[F_KIND] = 2.0
            fv[F_OUT + 10] = 1.0
    else:
        recent[iv[I_RI], 0] = cx
        recent[iv[I_RI], 1] = cy
    iv[I_RI] = (iv[I_RI] + 1) % recent.shape[0]
    # The wrench (the force at the axis point, r × F about the body's centre of mass) replaces last step's.
    c3 = _carray(_f64(iv[I_XIPOS]), 3)
    rx, ry, rz = cx - c3[0], cy - c3[1], z_mid - c3[2]
    wrench = (fx, fy, 0.0, -rz * fy, rz * fx, rx * fy - ry * fx)
    xfrc = _carray(_f64(iv[I_XFRC]), 6)
    for q in range(6):
        delta = wrench[q] - fv[F_APPLIED + q]
        xfrc[q] += delta
        fv[F_APPLIED + q] = wrench[q]
    load = 0.0
    if torque > 0:
        load = -math.copysign(_pmin(torque, fv[F_INERTIA] * abs(omega) / dt), omega)
    qfrc = _carray(_f64(iv[I_QFRC]), 1)
    qfrc[0] += load - fv[F_TORQUE_APPLIED]
    fv[F_TORQUE_APPLIED] = load
    return outcome, n_inside


def _spindle(fv: np.ndarray, reference: float, speed: float, time: float, dt: float) -> tuple[float, bool]:
    """``tools.SpindleLoop.control`` on the state in ``fv[F_SP:]`` (integral, stalled, low_since
    set, low_since), in the same operations (Python's ``min``/``max`` as ``_pmin``/``_pmax``):
    (the actuator set-point, whether a stall tripped now; the caller appends the event)."""
    if reference <= 0.0:
        fv[F_SP] = 0.0
        fv[F_SP + 1] = 0.0
        fv[F_SP + 2] = 0.0
        fv[F_SP + 3] = 0.0
        return 0.0, False
    if fv[F_SP + 1] != 0.0:
        return 0.0, False
    kv, ki, max_torque = fv[F_SP_OPT], fv[F_SP_OPT + 1], fv[F_SP_OPT + 2]
    error = reference - speed
    torque = kv * error + fv[F_SP]
    saturated = abs(torque) >= max_torque and torque * error > 0
    if not saturated:
        fv[F_SP] = _pmin(_pmax(fv[F_SP] + ki * error * dt, -max_torque), max_torque)
    if speed < fv[F_SP_OPT + 3] * reference:
        if fv[F_SP + 2] == 0.0:
            fv[F_SP + 2] = 1.0
            fv[F_SP + 3] = time
        if time - fv[F_SP + 3] >= fv[F_SP_OPT + 4]:
            fv[F_SP + 1] = 1.0
            return 0.0, True
    else:
        fv[F_SP + 2] = 0.0
        fv[F_SP + 3] = 0.0
    return _pmin(_pmax(reference + fv[F_SP] / kv, 0.0), fv[F_SP_OPT + 5]), False


def _tick(material: np.ndarray, cut: np.ndarray, removed_at: np.ndarray, recent: np.ndarray, fv: np.ndarray,
          iv: np.ndarray, acc: np.ndarray, reference: float, time: float, dt: float) -> int:
    """All of ``FoamCutter.step`` and ``CuttingObserver``'s sums in one call: the spindle loop
    (``_spindle``, set-point written to ``ctrl``), ``_step``, the removed volume, and the
    CutState added to ``acc`` (``N_A`` slots, as the observer adds it: in the same order).

    Why: the hook runs every physics step (12,834 per default run) and its Python around
    ``_step`` (the PI loop, CutState, the observer's tuple add) cost more than the kernel.
    Returns 0, or ``TICK_STALL`` (a stall tripped: the caller appends the event, the speed
    is ``fv[F_OMEGA]``) or/and ``TICK_PYTHON`` (``_step`` declined: the spindle ran, the
    step and the sums are the caller's, on the Python path)."""
    omega = _carray(_f64(iv[I_QVEL]), 1)[0]
    ctrl, tripped = _spindle(fv, reference, omega, time, dt)
    _carray(_f64(iv[I_CTRL]), 1)[0] = ctrl
    flags = TICK_STALL if tripped else 0
    fv[F_DT] = dt
    fv[F_OMEGA] = omega
    fv[F_TIME] = time
    fv[F_STALLED] = fv[F_SP + 1]
    outcome, n_inside = _step(material, cut, removed_at, recent, fv, iv)
    fv[F_OUTCOME] = outcome
    if outcome == STEP_PYTHON:
        return flags | TICK_PYTHON
    fv[F_UNBLOCK] = 1.0
    fv[F_LAZY] = 1.0
    active = False
    if n_inside:
        before = fv[F_REMOVED]
        fv[F_REMOVED] = before + n_inside * fv[F_VOXEL]
        fv[F_DIRTY] = 1.0
        active = fv[F_REMOVED] > before
    if fv[F_KIND] != 0.0:  # (kind 0 is the all-zero state: the observer skips it)
        acc[0] += fv[F_OUT]
        acc[1] += fv[F_OUT + 1]
        acc[2] += 0.0
        acc[3] += fv[F_OUT + 2]  # feed force
        acc[4] += fv[F_OUT + 3]  # normal force
        acc[5] += fv[F_OUT + 4]  # torque
        acc[6] += fv[F_OUT + 6]  # power (the observer's order: power before mrr)
        acc[7] += fv[F_OUT + 5]  # mrr
        acc[8] += fv[F_OUT + 7]  # depth
        acc[9] += fv[F_OUT + 8]  # chip
        if active:
            acc[A_ACTIVE] = 1.0
    acc[A_STEPS] += 1.0
    return flags


def _implicit_feed(fv: np.ndarray, iv: np.ndarray, nv: int, vx: float, vy: float, ex: float, ey: float, a: float,
                   b: float, dt: float, x: float, y: float) -> float:
    """``FoamCutter._implicit_feed``: the end-of-step feed speed, >= 0."""
    point = _carray(_f64(iv[I_POINT]), 3)
    point[0] = x
    point[1] = y
    _call_jac(iv[I_JAC], iv[I_M], iv[I_D], iv[I_JACBUF], iv[I_NULL], iv[I_POINT], iv[I_BODY])
    _call_solve(iv[I_SOLVE], iv[I_M], iv[I_D], iv[I_MINV], iv[I_JACBUF], iv[I_TWO])
    jxy = _carray(_f64(iv[I_JACBUF]), (2, nv))
    minv_jt = _carray(_f64(iv[I_MINV]), (2, nv))
    inv_l = np.dot(jxy, minv_jt.T)  # dgemm, as numpy's
    applied = np.empty(2)
    applied[0] = fv[F_APPLIED]
    applied[1] = fv[F_APPLIED + 1]
    acc = np.dot(jxy, _carray(_f64(iv[I_QACC]), nv)) - np.dot(inv_l, applied)  # dgemv, dgemv
    w = (vx + dt * acc[0]) * ex + (vy + dt * acc[1]) * ey
    e = np.empty(2)
    g = np.empty(2)
    e[0] = ex
    e[1] = ey
    g[0] = a * ex - b * ey
    g[1] = a * ey + b * ex
    gain = np.dot(np.dot(e, inv_l), g)  # dgemv, ddot
    return _pmax(w, 0.0) / (1.0 + dt * _pmax(gain, 0.0))


def _bind_intrinsics() -> None:
    """``_f64`` (an address as a float64 pointer, for ``carray``) and ``_call_jac``/``_call_solve``
    (MuJoCo's ``mj_jac``/``mj_solveM`` called through their addresses, all arguments int64).
    Addresses come in as arguments, none is baked into the code: numba's cache keeps working."""
    from llvmlite import ir
    from numba import carray, types
    from numba.extending import intrinsic

    ptr_t = ir.IntType(8).as_pointer()

    def f64(_typingctx: Any, _addr: Any) -> Any:
        def codegen(context: Any, builder: Any, _signature: Any, args: Any) -> Any:
            return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))
        return types.CPointer(types.float64)(types.int64), codegen

    def caller(n_pointers: int) -> Any:
        """The typing of ``void f(void*, ...(n_pointers), int)`` called through an int64 address."""
        def codegen(context: Any, builder: Any, _signature: Any, values: Any) -> Any:
            fnty = ir.FunctionType(ir.VoidType(), [ptr_t] * n_pointers + [ir.IntType(32)])
            fn = builder.inttoptr(values[0], fnty.as_pointer())
            builder.call(fn, [builder.inttoptr(v, ptr_t) for v in values[1:-1]] + [builder.trunc(values[-1], ir.IntType(32))])
            return context.get_dummy_value()
        return types.void(*([types.int64] * (n_pointers + 2))), codegen

    def call_jac(_typingctx: Any, _fn: Any, _m: Any, _d: Any, _jacp: Any, _jacr: Any, _point: Any, _body: Any) -> Any:
        return caller(5)

    def call_solve(_typingctx: Any, _fn: Any, _m: Any, _d: Any, _x: Any, _y: Any, _n: Any) -> Any:
        return caller(4)

    g = globals()
    g.update(_carray=carray, _f64=intrinsic(f64), _call_jac=intrinsic(call_jac), _call_solve=intrinsic(call_solve))


def mujoco_functions() -> tuple[int, int] | None:
    """The addresses of ``mj_jac`` and ``mj_solveM`` in the loaded MuJoCo library (None: not
    found; the cutter then runs its Python step)."""
    from ..plant.mujoco_native import mujoco_symbols

    found = mujoco_symbols("mj_jac", "mj_solveM")
    return None if found is None else (found[0], found[1])


def kernels() -> dict[str, Any]:
    """The compiled kernels ``engage``, ``remove``, ``held_anchored``, ``free_loose``,
    ``columns_with_material``, ``hypot`` and ``tick`` (``_step`` runs inside ``tick``)
    (compiled, or loaded from numba's cache, on first use)."""
    if not _KERNELS:
        _bind_intrinsics()
        jit_in_place(globals(), ("_pmax", "_pmin", "_two_product", "_hypot", "_index_range", "_block_sum", "_pairwise_sum", "_inside", "_engage", "_remove",
                                 "_push", "_flood", "_held_anchored", "_free_loose", "_columns_with_material",
                                 "_implicit_feed", "_step", "_spindle", "_tick"))
        _KERNELS.update(engage=_engage, remove=_remove, held_anchored=_held_anchored, free_loose=_free_loose,
                        columns_with_material=_columns_with_material, hypot=_hypot, tick=_tick)
    return _KERNELS
