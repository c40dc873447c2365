"""numba kernels of the control tick (``control.ArmController.update``), bit-identical to its Python path.

One configuration per call, state in numpy arrays. The Python path they replace
(``kinematics.ArmKernel.pose_jacobian``, ``kinematics.CableKernel.lengths``, the scalar code
of ``control``) mixes plain floats with a few numpy/BLAS calls; each piece is written here in
the floating-point order the original produces, so closed- and open-loop runs give the same
numbers (``tests/test_control_kernels.py`` compares them on random inputs):

* scalar Python arithmetic is written as is (no fast-math, no contraction to fused
  multiply-adds), ``math.sin``/``cos``/``atan2``/``sqrt`` are the same libm calls;
* ``math.hypot`` is CPython's own correctly-rounded algorithm, not libm's (``_hypot``);
* numpy's ``J @ J.T`` (OpenBLAS ``dsyrk``) and the 2×3 @ 3×2S product (``dgemm`` small
  kernel) accumulate each entry in one fused multiply-add chain, k = 0, 1, ... (``_fma``);
* ``J.T @ x``, ``gain @ step`` and the cable gather (``dgemv``) call BLAS through
  ``np.dot`` as numpy does (SciPy's OpenBLAS; numpy's is its own build of the same library);
* ``np.einsum`` over three terms sums ``(t0 + t2) + t1`` (its two-lane accumulation);
* the 6×6 solve is LAPACK's ``dposv``, the routine ``control._solve_spd`` calls, called by
  its address (``_dposv_call``).

The BLAS orders were read off this machine's OpenBLAS (AVX-512/FMA kernels); the equality
tests would show if another platform's kernels summed differently.

Lazy: nothing imports numba until a controller is built.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba.extending import intrinsic

from .plant.jit import jit_in_place

_KERNELS: dict[str, Any] = {}
_DBL_MIN = 2.2250738585072014e-308


@intrinsic
def _fma(typingctx: Any, a: Any, b: Any, c: Any) -> Any:  # noqa: ARG001 - numba intrinsic (typing context, argument types)
    """a·b + c rounded once (llvm.fma), as OpenBLAS's FMA kernels accumulate."""
    from numba.core import types

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:  # noqa: ARG001
        return builder.fma(*args)

    return types.float64(types.float64, types.float64, types.float64), codegen


@intrinsic
def _dposv_call(typingctx: Any, addr: Any, uplo: Any, ints: Any, a: Any, b: Any) -> Any:  # noqa: ARG001 - numba intrinsic
    """LAPACK dposv(uplo, n, nrhs, a, lda, b, ldb, info) through its address ``addr`` (an int, given at run time).

    ``ints`` (int32): n, nrhs, lda, ldb, info. The address is an argument, not a constant,
    so the compiled code stays cacheable; it is SciPy's ``cython_lapack.dposv``, the same
    OpenBLAS routine ``scipy.linalg.lapack.dposv`` (``control._solve_spd``) calls.
    """
    from llvmlite import ir
    from numba.core import types

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        i8p, i32p, f64p = ir.IntType(8).as_pointer(), ir.IntType(32).as_pointer(), ir.DoubleType().as_pointer()
        data = [context.make_array(t)(context, builder, v).data for t, v in zip(signature.args[1:], args[1:])]
        n = builder.bitcast(data[1], i32p)

        def at(k: int) -> Any:
            return builder.gep(n, [ir.Constant(ir.IntType(64), k)])

        fnty = ir.FunctionType(ir.VoidType(), [i8p, i32p, i32p, f64p, i32p, f64p, i32p, i32p])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        a_ptr, b_ptr = builder.bitcast(data[2], f64p), builder.bitcast(data[3], f64p)
        builder.call(fn, [builder.bitcast(data[0], i8p), at(0), at(1), a_ptr, at(2), b_ptr, at(3), at(4)])
        return context.get_dummy_value()

    return types.void(addr, uplo, ints, a, b), codegen


def dposv_address() -> int:
    """Address of SciPy's ``cython_lapack.dposv`` (for ``_tick``)."""
    from numba.extending import get_cython_function_address

    return int(get_cython_function_address("scipy.linalg.cython_lapack", "dposv"))


def _solve_spd(addr: int, uplo: np.ndarray, ints: np.ndarray, A: np.ndarray, a_work: np.ndarray, x: np.ndarray) -> int:
    """x ← A⁻¹x by dposv on a copy of A (A symmetric: row-major = column-major); returns LAPACK's info."""
    m = A.shape[0]
    for i in range(m):
        for j in range(m):
            a_work[i, j] = A[j, i]
    ints[0], ints[1], ints[2], ints[3], ints[4] = m, 1, m, m, 0
    _dposv_call(addr, uplo, ints, a_work, x)  # type: ignore[call-arg]
    return int(ints[4])


def _hypot(a: float, b: float) -> float:
    """CPython 3.11's ``math.hypot(a, b)`` (``vector_norm``: Dekker products, compensated sums).

    numba's ``math.hypot`` is libm's, which differs in the last bit for ~0.4 % of inputs.
    """
    x0, x1 = abs(a), abs(b)
    if math.isinf(x0) or math.isinf(x1):
        return math.inf
    if math.isnan(x0) or math.isnan(x1):
        return math.nan
    mx = x0 if x0 > x1 else x1
    if mx == 0.0:
        return mx
    factor = 1.0
    _, e = math.frexp(mx)
    if e < -1023:  # subnormal: scale to normal numbers first
        x0, x1, factor = x0 / _DBL_MIN, x1 / _DBL_MIN, _DBL_MIN
        _, e = math.frexp(x0 if x0 > x1 else x1)
    scale = math.ldexp(1.0, -e)
    csum, frac1, frac2 = 1.0, 0.0, 0.0
    for i in range(2):
        x = (x0 if i == 0 else x1) * scale
        t = x * 134217729.0
        hi = t - (t - x)
        lo = x - hi
        p = hi * hi
        q = hi * lo + lo * hi
        z = p + q
        zz = p - z + q + lo * lo
        s = csum + z
        frac2 += (csum - s) + z
        csum = s
        frac1 += zz
    h = math.sqrt(csum - 1.0 + (frac1 + frac2))
    nh = -h
    t = nh * 134217729.0
    hi1 = t - (t - nh)
    lo1 = nh - hi1
    t = h * 134217729.0
    hi2 = t - (t - h)
    lo2 = h - hi2
    p = hi1 * hi2
    q = hi1 * lo2 + lo1 * hi2
    z = p + q
    zz = p - z + q + lo1 * lo2
    s = csum + z
    frac2 += (csum - s) + z
    csum = s
    frac1 += zz
    x = csum - 1.0 + (frac1 + frac2)
    h += x / (2.0 * h)
    return factor * (h / scale)


def _dsinc_over_x(x: float) -> float:
    """``kinematics._dsinc_over_x_scalar``."""
    if abs(x) < 1e-2:
        x2 = x * x
        return -1.0 / 3.0 + x2 / 30.0 - x2 * x2 / 840.0 + x2 * x2 * x2 / 45360.0
    return (x * math.cos(x) - math.sin(x)) / (x * x * x)


def _one_minus_sinc_over_sq(x: float) -> float:
    """``kinematics._one_minus_sinc_over_sq_scalar``."""
    if abs(x) < 1e-2:
        x2 = x * x
        return 1.0 / 6.0 - x2 / 120.0 + x2 * x2 / 5040.0
    return (x - math.sin(x)) / (x * x * x)


def _pose_jacobian(lengths: np.ndarray, segments: np.ndarray, tool_length: float, w: np.ndarray, R: np.ndarray, p: np.ndarray, J: np.ndarray) -> None:
    """``kinematics.ArmKernel.pose_jacobian(w)`` into R (9,), p (3,), J (6·2S,), row-major; same operations."""
    S = lengths.shape[0]
    m = 2 * S
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    px = py = pz = 0.0
    cols = np.empty((m, 6))
    ends = np.empty((S, 3))
    for k in range(S):
        L = lengths[k]
        n = segments[k]
        u = w[2 * k]
        v = w[2 * k + 1]
        t = math.sqrt(u * u + v * v)
        a = t / (2.0 * n)
        h = 0.5 * t
        ca = math.cos(a)
        sin_t = 0.0
        if t < 1e-4:
            t2 = t * t
            a2 = a * a
            h2 = h * h
            sa = 1.0 - a2 / 6.0 + a2 * a2 / 120.0
            sh = 1.0 - h2 / 6.0 + h2 * h2 / 120.0
            st = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
        else:
            sin_t = math.sin(t)
            sa = math.sin(a) / a
            sh = math.sin(h) / h
            st = sin_t / t
        G = 0.5 * L * ca * sh * sh / sa
        Z = L * ca * st / sa
        A = st
        B = 0.5 * sh * sh
        s00 = 1.0 - B * u * u
        s01 = -B * u * v
        s02 = A * u
        s11 = 1.0 - B * v * v
        s12 = A * v
        s22 = 1.0 - B * t * t
        lx, ly, lz = G * u, G * v, Z
        n2 = 4.0 * n * n
        da = _dsinc_over_x(a)
        if t < 1e-2:
            dh = _dsinc_over_x(h)
            dt = _dsinc_over_x(t)
            C = _one_minus_sinc_over_sq(t)
        else:
            cos_t = math.cos(t)
            t3 = t * t * t
            dh = (h * math.cos(h) - math.sin(h)) / (h * h * h)
            dt = (t * cos_t - sin_t) / t3
            C = (t - sin_t) / t3
        Gp = 0.5 * L * (-sh * sh / n2 + ca * sh * dh / (2.0 * sa) - ca * sh * sh * da / (n2 * sa * sa))
        Zp = L * (-st / n2 + ca * dt / sa - ca * st * da / (n2 * sa * sa))
        for c in range(2):
            if c == 0:
                d0, d1, d2 = G + u * u * Gp, u * v * Gp, u * Zp
                o0, o1, o2 = -C * u * v, 1.0 - C * v * v, -B * v
            else:
                d0, d1, d2 = u * v * Gp, G + v * v * Gp, v * Zp
                o0, o1, o2 = -(1.0 - C * u * u), C * u * v, B * u
            col = 2 * k + c
            cols[col, 0] = r00 * d0 + r01 * d1 + r02 * d2
            cols[col, 1] = r10 * d0 + r11 * d1 + r12 * d2
            cols[col, 2] = r20 * d0 + r21 * d1 + r22 * d2
            cols[col, 3] = r00 * o0 + r01 * o1 + r02 * o2
            cols[col, 4] = r10 * o0 + r11 * o1 + r12 * o2
            cols[col, 5] = r20 * o0 + r21 * o1 + r22 * o2
        px, py, pz = (
            px + r00 * lx + r01 * ly + r02 * lz,
            py + r10 * lx + r11 * ly + r12 * lz,
            pz + r20 * lx + r21 * ly + r22 * lz,
        )
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = (
            r00 * s00 + r01 * s01 - r02 * s02,
            r00 * s01 + r01 * s11 - r02 * s12,
            r00 * s02 + r01 * s12 + r02 * s22,
            r10 * s00 + r11 * s01 - r12 * s02,
            r10 * s01 + r11 * s11 - r12 * s12,
            r10 * s02 + r11 * s12 + r12 * s22,
            r20 * s00 + r21 * s01 - r22 * s02,
            r20 * s01 + r21 * s11 - r22 * s12,
            r20 * s02 + r21 * s12 + r22 * s22,
        )
        ends[k, 0], ends[k, 1], ends[k, 2] = px, py, pz
    Px, Py, Pz = px + tool_length * r02, py + tool_length * r12, pz + tool_length * r22
    R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7], R[8] = r00, r01, r02, r10, r11, r12, r20, r21, r22
    p[0], p[1], p[2] = Px, Py, Pz
    for c in range(m):
        vx, vy, vz, ox, oy, oz = cols[c, 0], cols[c, 1], cols[c, 2], cols[c, 3], cols[c, 4], cols[c, 5]
        ax, ay, az = Px - ends[c // 2, 0], Py - ends[c // 2, 1], Pz - ends[c // 2, 2]
        J[c] = vx + oy * az - oz * ay
        J[m + c] = vy + oz * ax - ox * az
        J[2 * m + c] = vz + ox * ay - oy * ax
        J[3 * m + c] = ox
        J[4 * m + c] = oy
        J[5 * m + c] = oz


def _sinc(x: float) -> float:
    """``kinematics._sinc_scalar``."""
    if abs(x) < 1e-4:
        x2 = x * x
        return 1.0 - x2 / 6.0 + x2 * x2 / 120.0
    return math.sin(x) / x


def _cable_lengths(
    w: np.ndarray, segments: np.ndarray, halves: np.ndarray, pair_section: np.ndarray, pair_holes: np.ndarray, gather: np.ndarray, out: np.ndarray
) -> None:
    """``kinematics.CableKernel.lengths(w)`` into ``out``: its einsums' order, its BLAS gather."""
    S = segments.shape[0]
    coef = np.empty((S, 3, 3))
    for m in range(S):
        n = segments[m]
        half = halves[m]
        rx, ry = -w[2 * m + 1] / n, w[2 * m] / n
        angle2 = rx * rx + ry * ry
        angle = math.sqrt(angle2)
        A = _sinc(angle)
        if angle < 1e-2:
            B = 0.5 - angle2 / 24.0 + angle2 * angle2 / 720.0
        else:
            B = (1.0 - math.cos(angle)) / angle2
        bxy = B * rx * ry
        coef[m, 0, 0], coef[m, 0, 1], coef[m, 0, 2] = -B * ry * ry, bxy, A * ry * half
        coef[m, 1, 0], coef[m, 1, 1], coef[m, 1, 2] = bxy, -B * rx * rx, -A * rx * half
        coef[m, 2, 0], coef[m, 2, 1], coef[m, 2, 2] = -A * ry, A * rx, (2.0 - B * angle2) * half
    P = pair_section.shape[0]
    norms = np.empty(P)
    for q in range(P):
        m = pair_section[q]
        h0, h1, h2 = pair_holes[q, 0], pair_holes[q, 1], pair_holes[q, 2]
        s0 = (coef[m, 0, 0] * h0 + coef[m, 0, 2] * h2) + coef[m, 0, 1] * h1
        s1 = (coef[m, 1, 0] * h0 + coef[m, 1, 2] * h2) + coef[m, 1, 1] * h1
        s2 = (coef[m, 2, 0] * h0 + coef[m, 2, 2] * h2) + coef[m, 2, 1] * h1
        norms[q] = math.sqrt((s0 * s0 + s2 * s2) + s1 * s1)
    out[:] = np.dot(gather, norms)


def _set_points(  # noqa: PLR0913
    w: np.ndarray, segments: np.ndarray, halves: np.ndarray, pair_section: np.ndarray, pair_holes: np.ndarray, gather: np.ndarray,
    offset: np.ndarray, extra: np.ndarray, cable_section: np.ndarray, out: np.ndarray,
) -> None:
    """``control.ArmController._cable_set_points``: cable lengths less the pre-tension offset and the common mode."""
    _cable_lengths(w, segments, halves, pair_section, pair_holes, gather, out)
    for c in range(out.shape[0]):
        out[c] = out[c] - offset[c] - extra[cable_section[c]]


def _commanded(q_plan: np.ndarray, correction: np.ndarray, proportional: np.ndarray, max_bend: np.ndarray, w: np.ndarray) -> None:
    """``control.ArmController._commanded`` into ``w``: plan + correction + proportional, bend-limited."""
    for k in range(max_bend.shape[0]):
        theta, phi = q_plan[2 * k], q_plan[2 * k + 1]
        u = theta * math.cos(phi) + correction[2 * k] + proportional[2 * k]
        v = theta * math.sin(phi) + correction[2 * k + 1] + proportional[2 * k + 1]
        bend, mb = _hypot(u, v), max_bend[k]
        if bend > mb:
            u, v = u * mb / bend, v * mb / bend
        w[2 * k] = u
        w[2 * k + 1] = v


def _rotation_error(t: np.ndarray, a: np.ndarray, r: np.ndarray) -> bool:
    """``control._rotation_error_scalar`` into r (3,); False (r untouched) beyond 3 rad, where it takes log_so3."""
    e00 = t[0] * a[0] + t[1] * a[1] + t[2] * a[2]
    e11 = t[3] * a[3] + t[4] * a[4] + t[5] * a[5]
    e22 = t[6] * a[6] + t[7] * a[7] + t[8] * a[8]
    e01 = t[0] * a[3] + t[1] * a[4] + t[2] * a[5]
    e10 = t[3] * a[0] + t[4] * a[1] + t[5] * a[2]
    e02 = t[0] * a[6] + t[1] * a[7] + t[2] * a[8]
    e20 = t[6] * a[0] + t[7] * a[1] + t[8] * a[2]
    e12 = t[3] * a[6] + t[4] * a[7] + t[5] * a[8]
    e21 = t[6] * a[3] + t[7] * a[4] + t[8] * a[5]
    vx, vy, vz = 0.5 * (e21 - e12), 0.5 * (e02 - e20), 0.5 * (e10 - e01)
    sin = math.sqrt(vx * vx + vy * vy + vz * vz)
    cos = 0.5 * (e00 + e11 + e22 - 1.0)
    angle = math.atan2(sin, cos)
    if angle > 3.0:
        return False
    scale = angle / sin if sin > 1e-12 else 1.0
    r[0], r[1], r[2] = vx * scale, vy * scale, vz * scale
    return True


def _tick_system(  # noqa: PLR0913
    plan: np.ndarray, pos: np.ndarray, mat: np.ndarray, b: np.ndarray, w: np.ndarray, lengths: np.ndarray, segments: np.ndarray, tool_length: float, ow: float,
    roll_free: bool, regulariser: np.ndarray, r: np.ndarray, have_r: bool,
    R: np.ndarray, p: np.ndarray, Jflat: np.ndarray, J: np.ndarray, error: np.ndarray, A: np.ndarray,
) -> bool:
    """The damped-least-squares system of ``control.ArmController._integrate``: J (m×2S), error (m,), A = J Jᵀ + λI.

    ``plan`` (4×4) the planned tool pose, ``pos``/``mat`` the measured one (world), ``b`` the
    base rotation's transpose. ``have_r``: ``r`` already holds the rotation error (Python's
    log_so3 fallback); otherwise it is computed here, and False is returned beyond 3 rad.
    """
    if not have_r:
        t9 = np.empty(9)
        for i in range(3):
            for j in range(3):
                t9[3 * i + j] = plan[i, j]
        if not _rotation_error(t9, mat.ravel(), r):
            return False
    dx, dy, dz = plan[0, 3] - pos[0], plan[1, 3] - pos[1], plan[2, 3] - pos[2]
    rx, ry, rz = r[0], r[1], r[2]
    rows = np.empty(6)
    rows[0] = b[0, 0] * dx + b[0, 1] * dy + b[0, 2] * dz
    rows[1] = b[1, 0] * dx + b[1, 1] * dy + b[1, 2] * dz
    rows[2] = b[2, 0] * dx + b[2, 1] * dy + b[2, 2] * dz
    rows[3] = ow * (b[0, 0] * rx + b[0, 1] * ry + b[0, 2] * rz)
    rows[4] = ow * (b[1, 0] * rx + b[1, 1] * ry + b[1, 2] * rz)
    rows[5] = ow * (b[2, 0] * rx + b[2, 1] * ry + b[2, 2] * rz)
    _pose_jacobian(lengths, segments, tool_length, w, R, p, Jflat)
    n = w.shape[0]
    for i in range(3):
        error[i] = rows[i]
        for c in range(n):
            J[i, c] = Jflat[i * n + c]
    if not roll_free:
        for i in range(3, 6):
            error[i] = rows[i]
            for c in range(n):
                J[i, c] = Jflat[i * n + c] * ow
    else:
        # Tool x and y axes in the base frame; the angular rows about them only.
        Jw = np.empty((3, n))
        for i in range(3):
            for c in range(n):
                Jw[i, c] = Jflat[(3 + i) * n + c] * ow
        for j in range(2):
            a0 = b[0, 0] * mat[0, j] + b[0, 1] * mat[1, j] + b[0, 2] * mat[2, j]
            a1 = b[1, 0] * mat[0, j] + b[1, 1] * mat[1, j] + b[1, 2] * mat[2, j]
            a2 = b[2, 0] * mat[0, j] + b[2, 1] * mat[1, j] + b[2, 2] * mat[2, j]
            error[3 + j] = ((0.0 + a0 * rows[3]) + a1 * rows[4]) + a2 * rows[5]  # Python's sum()
            for c in range(n):
                J[3 + j, c] = _fma(a2, Jw[2, c], _fma(a1, Jw[1, c], a0 * Jw[0, c]))  # type: ignore[call-arg]  # dgemm FMA chain
    m = error.shape[0]
    for i in range(m):
        for j in range(m):
            s = J[i, 0] * J[j, 0]
            for k in range(1, n):
                s = _fma(J[i, k], J[j, k], s)  # type: ignore[call-arg]  # dsyrk FMA chain
            A[i, j] = s + regulariser[i, j]
    return True


def _tick_step(  # noqa: PLR0913
    J: np.ndarray, x: np.ndarray, correction: np.ndarray, proportional: np.ndarray, gain: np.ndarray, use_gain: bool,
    outer_gain: float, dt: float, outer_proportional: float, max_correction: float,
) -> None:
    """Step = Jᵀx; integrate it into the correction (scalar gain or matrix), set the proportional share, bound per section."""
    step = np.dot(J.T, x)
    if use_gain:
        gs = np.dot(gain, step)
        for i in range(correction.shape[0]):
            correction[i] += dt * gs[i]
    else:
        g = outer_gain * dt
        for i in range(correction.shape[0]):
            correction[i] += g * step[i]
    for i in range(correction.shape[0]):
        proportional[i] = outer_proportional * step[i]
    for k in range(correction.shape[0] // 2):
        norm = _hypot(correction[2 * k], correction[2 * k + 1])
        if norm > max_correction:
            f = max_correction / norm
            correction[2 * k] *= f
            correction[2 * k + 1] *= f


def _keep_tension(
    tensions: np.ndarray, extra: np.ndarray, cable_kp: np.ndarray, min_tension: float, tension_gain: float, max_extra_tension: float, dt: float
) -> None:
    """``control.ArmController._keep_tension``: numpy's min (NaN propagates) and clip, per section."""
    for s in range(extra.shape[0]):
        t0, t1, t2 = tensions[3 * s], tensions[3 * s + 1], tensions[3 * s + 2]
        slackest = t0
        if t1 < slackest:
            slackest = t1
        if t2 < slackest:
            slackest = t2
        if math.isnan(t0) or math.isnan(t1) or math.isnan(t2):
            slackest = math.nan
        x = extra[s] + tension_gain * (min_tension - slackest) / cable_kp[s] * dt
        hi = max_extra_tension / cable_kp[s]
        x = x if (x >= 0.0 or math.isnan(x)) else 0.0
        x = x if (x <= hi or math.isnan(x)) else hi
        extra[s] = x


def _tick_begin(  # noqa: PLR0913
    q_plan: np.ndarray, correction: np.ndarray, proportional: np.ndarray, max_bend: np.ndarray, w: np.ndarray,
    integrate: bool, plan: np.ndarray, pos: np.ndarray, mat: np.ndarray, b: np.ndarray, lengths: np.ndarray,
    segments: np.ndarray, tool_length: float, ow: float, roll_free: bool, regulariser: np.ndarray, r: np.ndarray,
    R: np.ndarray, p: np.ndarray, Jflat: np.ndarray, J: np.ndarray, error: np.ndarray, A: np.ndarray,
) -> bool:
    """First half of a tick, one call: the commanded shape and, when ``integrate``, the DLS system (False: > 3 rad)."""
    _commanded(q_plan, correction, proportional, max_bend, w)
    if not integrate:
        return True
    return _tick_system(
        plan, pos, mat, b, w, lengths, segments, tool_length, ow, roll_free, regulariser, r, False, R, p, Jflat, J, error, A
    )


def _tick_end(  # noqa: PLR0913
    integrated: bool, J: np.ndarray, x: np.ndarray, correction: np.ndarray, proportional: np.ndarray,
    gain: np.ndarray, use_gain: bool, outer_gain: float, dt: float, outer_proportional: float, max_correction: float,
    q_plan: np.ndarray, max_bend: np.ndarray, w: np.ndarray,
    keep: bool, tensions: np.ndarray, extra: np.ndarray, cable_kp: np.ndarray, min_tension: float,
    tension_gain: float, max_extra_tension: float,
    cable_segments: np.ndarray, halves: np.ndarray, pair_section: np.ndarray, pair_holes: np.ndarray,
    gather: np.ndarray, offset: np.ndarray, cable_section: np.ndarray, out: np.ndarray,
) -> None:
    """Second half, one call: step and correction, the shape again, tension keeping, the cable set-points."""
    if integrated:
        _tick_step(J, x, correction, proportional, gain, use_gain, outer_gain, dt, outer_proportional, max_correction)
        _commanded(q_plan, correction, proportional, max_bend, w)
    if keep:
        _keep_tension(tensions, extra, cable_kp, min_tension, tension_gain, max_extra_tension, dt)
    _set_points(w, cable_segments, halves, pair_section, pair_holes, gather, offset, extra, cable_section, out)


def _tick(  # noqa: PLR0913
    q_plan: np.ndarray, correction: np.ndarray, proportional: np.ndarray, max_bend: np.ndarray, w: np.ndarray,
    plan: np.ndarray, pos: np.ndarray, mat: np.ndarray, b: np.ndarray, lengths: np.ndarray,
    segments: np.ndarray, tool_length: float, ow: float, roll_free: bool, regulariser: np.ndarray, r: np.ndarray,
    R: np.ndarray, p: np.ndarray, Jflat: np.ndarray, J: np.ndarray, error: np.ndarray, A: np.ndarray,
    dposv: int, uplo: np.ndarray, ints: np.ndarray, a_work: np.ndarray, x: np.ndarray,
    gain: np.ndarray, use_gain: bool, outer_gain: float, dt: float, outer_proportional: float, max_correction: float,
    keep: bool, tensions: np.ndarray, extra: np.ndarray, cable_kp: np.ndarray, min_tension: float,
    tension_gain: float, max_extra_tension: float,
    cable_segments: np.ndarray, halves: np.ndarray, pair_section: np.ndarray, pair_holes: np.ndarray,
    gather: np.ndarray, offset: np.ndarray, cable_section: np.ndarray, out: np.ndarray,
) -> int:
    """A whole integrating tick in one call: 0 done; 1 (rotation error beyond 3 rad) or 2 (A not positive
    definite): stopped before any state changed, with ``w`` commanded (and for 2 the system in J, error, A),
    for the caller's Python fallback."""
    if not _tick_begin(
        q_plan, correction, proportional, max_bend, w, True, plan, pos, mat, b, lengths, segments, tool_length, ow,
        roll_free, regulariser, r, R, p, Jflat, J, error, A,
    ):
        return 1
    for i in range(error.shape[0]):
        x[i] = error[i]
    if _solve_spd(dposv, uplo, ints, A, a_work, x) != 0:
        return 2
    _tick_end(
        True, J, x, correction, proportional, gain, use_gain, outer_gain, dt, outer_proportional, max_correction,
        q_plan, max_bend, w, keep, tensions, extra, cable_kp, min_tension, tension_gain, max_extra_tension,
        cable_segments, halves, pair_section, pair_holes, gather, offset, cable_section, out,
    )
    return 0


def _plan_at(times: np.ndarray, t: float, q: np.ndarray, tcp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``controllers.plan_at``: the sample index and fraction at ``t``, then ``(1 - f)·a + f·b`` (numpy's order)."""
    n = times.shape[0]
    x = (t - times[0]) / (times[1] - times[0])
    if 0.0 > x:  # Python's max(x, 0.0), min(., n - 1.0)
        x = 0.0
    if n - 1.0 < x:
        x = n - 1.0
    i0 = min(int(x), n - 2)
    f = x - i0
    g = 1.0 - f
    q_out = np.empty(q.shape[1])
    for j in range(q.shape[1]):
        q_out[j] = g * q[i0, j] + f * q[i0 + 1, j]
    tcp_out = np.empty((tcp.shape[1], tcp.shape[2]))
    for i in range(tcp.shape[1]):
        for j in range(tcp.shape[2]):
            tcp_out[i, j] = g * tcp[i0, i, j] + f * tcp[i0 + 1, i, j]
    return q_out, tcp_out


def kernels() -> dict[str, Any]:
    """The compiled kernels (compiled, or loaded from numba's cache, on first use)."""
    if not _KERNELS:
        jit_in_place(
            globals(),
            ("_hypot", "_dsinc_over_x", "_one_minus_sinc_over_sq", "_sinc", "_pose_jacobian", "_cable_lengths", "_set_points",
             "_commanded", "_rotation_error", "_tick_system", "_tick_step", "_keep_tension", "_tick_begin", "_tick_end",
             "_plan_at", "_solve_spd", "_tick"),
        )
        _KERNELS.update(
            pose_jacobian=_pose_jacobian, cable_lengths=_cable_lengths, set_points=_set_points, commanded=_commanded,
            tick_system=_tick_system, tick_step=_tick_step, keep_tension=_keep_tension, hypot=_hypot,
            tick_begin=_tick_begin, tick_end=_tick_end, plan_at=_plan_at, solve_spd=_solve_spd, tick=_tick,
        )
    return _KERNELS
