"""The cutter's per-physics-step work, compiled (numba): the only implementation.

``begin`` (the cutter's axis point, the near test, the feed velocity, the engaged depth on
the leading half circle with the recent-centres exclusion) and ``finish`` (the cutting force
with the implicit feed, removal, the block spring, the wrench, the spindle load, the
observer's sums) share one ``CUTTER`` record; between them the caller fills the cutter
point's Jacobian and ``M⁻¹Jᵀ`` if ``begin`` asks for them. ``tick`` is the three in one call,
``mj_jac``/``mj_solveM`` called by address (``mujoco_native``); without MuJoCo's library by path
the cutter calls ``begin``, MuJoCo's public API, ``finish``. The physics is described in
``plant/cutter.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import carray

from .jit import jit
from .mujoco_native import call_jac, call_solve, f64

# The cutter's constants, state and last step's outputs (one record per cutter).
CUTTER = np.dtype([
    # constants
    ("lo", "f8", (3,)), ("h", "f8", (3,)), ("hi", "f8", (3,)), ("shape", "i8", (3,)),
    ("z_mid", "f8"), ("half", "f8"), ("radius", "f8"), ("probe", "f8"), ("probe2", "f8"),
    ("min_speed", "f8"), ("u", "f8"), ("radial", "f8"), ("inertia", "f8"), ("voxel", "f8"),
    ("block_stiffness", "f8"), ("block_damping", "f8"),
    # state
    ("recent_i", "i8"), ("applied", "f8", (6,)), ("torque_applied", "f8"), ("removed", "f8"), ("dirty", "i8"),
    ("block", "i8"), ("block_x", "f8"), ("block_y", "f8"), ("block_nx", "f8"), ("block_ny", "f8"), ("block_pen", "f8"),
    # between begin and finish
    ("cx", "f8"), ("cy", "f8"), ("z0", "f8"), ("z1", "f8"), ("vx", "f8"), ("vy", "f8"), ("ex", "f8"), ("ey", "f8"),
    ("omega", "f8"), ("speed", "f8"), ("near", "i8"), ("cutting_on", "i8"), ("feeding", "i8"), ("n_inside", "i8"),
    ("d_cc", "f8"), ("d_cs", "f8"), ("d_c", "f8"),
    # outputs of the last step (``cutter.CutState``)
    ("force", "f8", (2,)), ("feed_force", "f8"), ("normal_force", "f8"), ("torque", "f8"), ("mrr", "f8"),
    ("power", "f8"), ("depth", "f8"), ("chip", "f8"), ("feed_speed", "f8"), ("cutting", "i8"), ("blocked", "i8"),
])

# Addresses (int64) of what the kernels read and write in place: MuJoCo's model, data and
# rows of its buffers (live as long as the MjData), the cutter's work arrays, the functions.
POINTERS = np.dtype([
    ("model", "i8"), ("data", "i8"), ("jac_fn", "i8"), ("solve_fn", "i8"), ("body", "i8"), ("nv", "i8"),
    ("xpos", "i8"), ("xmat", "i8"), ("cvel", "i8"), ("com", "i8"), ("xipos", "i8"), ("xfrc", "i8"),
    ("qfrc", "i8"), ("qacc", "i8"), ("qvel", "i8"), ("jac", "i8"), ("minv", "i8"), ("point", "i8"),
])

# The observer's sums over a tick's steps (``cut_record.CuttingObserver``): all float64, so the
# observer reads them as one vector (``SUMS_MEANS`` the slots it averages, then the flags and the count).
SUMS = np.dtype([
    ("force", "f8", (3,)), ("feed_force", "f8"), ("normal_force", "f8"), ("torque", "f8"), ("power", "f8"),
    ("mrr", "f8"), ("depth", "f8"), ("chip", "f8"), ("active", "f8"), ("blocked", "f8"), ("steps", "f8"),
])
SUMS_MEANS = 10

# Rows of the per-probe constants ``probes`` (engagement angles θ: cos, sin, and the bin integrals).
P_COS, P_SIN, P_ICC, P_ICS, P_IC = range(5)


@jit
def _range(lo: float, h: float, n: int, a: float, b: float) -> tuple[int, int]:
    """[i0, i1) of the voxels whose centres may lie in [a, b] along one axis."""
    i0 = math.floor((a - lo) / h - 0.5)
    i1 = math.ceil((b - lo) / h + 0.5)
    return max(0, i0), min(n, i1)


@jit
def inside(material: np.ndarray, cut: np.ndarray, removed_at: np.ndarray, lo: np.ndarray, h: np.ndarray,
           cx: float, cy: float, z0: float, z1: float, r: float, remove: bool, time: float) -> tuple[int, float, float]:
    """The voxels of material whose centres lie inside the cutter (radius r about (cx, cy),
    z in [z0, z1]): (count, Σ dx, Σ dy) with dx, dy from the axis; with ``remove`` they are
    removed (``cut`` marks them, a column's first removal time goes to ``removed_at``)."""
    nx, ny, nz = material.shape
    i0, i1 = _range(lo[0], h[0], nx, cx - r, cx + r)
    j0, j1 = _range(lo[1], h[1], ny, cy - r, cy + r)
    k0, k1 = _range(lo[2], h[2], nz, z0, z1)
    rr = r * r
    count, sx, sy = 0, 0.0, 0.0
    for i in range(i0, i1):
        dx = lo[0] + (i + 0.5) * h[0] - cx
        for j in range(j0, j1):
            dy = lo[1] + (j + 0.5) * h[1] - cy
            if dx * dx + dy * dy > rr:
                continue
            hit = False
            for k in range(k0, k1):
                zc = lo[2] + (k + 0.5) * h[2]
                if material[i, j, k] and zc >= z0 and zc <= z1:
                    count += 1
                    sx += dx
                    sy += dy
                    if remove:
                        material[i, j, k] = False
                        cut[i, j, k] = True
                        hit = True
            if hit and math.isnan(removed_at[i, j]):
                removed_at[i, j] = time
    return count, sx, sy


@jit
def _layer_weights(s: np.record, k: int, z0: float, z1: float) -> float:
    """Length (m) of z layer k inside [z0, z1]."""
    lo, h = s.lo[2], s.h[2]
    v = min(lo + (k + 1) * h, z1) - max(lo + k * h, z0)
    return v if v > 0.0 else 0.0


@jit
def engage(material: np.ndarray, recent: np.ndarray, probes: np.ndarray, s: np.record) -> float:
    """The engaged depth a(θ) at the probe angles on the leading half circle (material depth in
    the probe's voxel column within the cutter's axial extent; 0 where a recent cutter centre
    reached the probe before): Σ a·I_cc, Σ a·I_cs, Σ a·I_c into the record; returns the mean a."""
    nx, ny, nz = material.shape
    cx, cy, ex, ey = s.cx, s.cy, s.ex, s.ey
    d_cc = d_cs = d_c = total = 0.0
    m = probes.shape[1]
    for p in range(m):
        qx = cx + s.probe * (ex * probes[P_COS, p] - ey * probes[P_SIN, p])
        qy = cy + s.probe * (ey * probes[P_COS, p] + ex * probes[P_SIN, p])
        reached = False
        for q in range(recent.shape[0]):
            ddx = qx - recent[q, 0]
            ddy = qy - recent[q, 1]
            if ddx * ddx + ddy * ddy < s.probe2:
                reached = True
                break
        if reached:
            continue
        i = int(math.floor((qx - s.lo[0]) / s.h[0]))
        j = int(math.floor((qy - s.lo[1]) / s.h[1]))
        if i < 0 or i >= nx or j < 0 or j >= ny:
            continue
        depth = 0.0
        for k in range(nz):
            if material[i, j, k]:
                depth += _layer_weights(s, k, s.z0, s.z1)
        d_cc += depth * probes[P_ICC, p]
        d_cs += depth * probes[P_ICS, p]
        d_c += depth * probes[P_IC, p]
        total += depth
    s.d_cc, s.d_cs, s.d_c = d_cc, d_cs, d_c
    return total / m


@jit
def begin(recent: np.ndarray, state: np.ndarray, ptr: np.ndarray, spindle: np.ndarray) -> bool:
    """The first half of a step: where the cutter is, whether it is near material, its feed
    velocity and whether it cuts (spindle fast enough and not stalled: ``spindle`` is the
    drive's record, read only). True when the force needs the Jacobian at the cutter point."""
    s, a = state[0], ptr[0]
    pos = carray(f64(a.xpos), 3)
    mat = carray(f64(a.xmat), 9)
    ax, ay, az = mat[2], mat[5], mat[8]  # the cutter axis (matrix column z)
    # The axis point at the plate's mid-plane (the cutter stands near the plate normal).
    along = (s.z_mid - pos[2]) / az if abs(az) > 0.5 else 0.0
    s.cx, s.cy = pos[0] + along * ax, pos[1] + along * ay
    s.z0 = pos[2] - s.half * abs(az)
    s.z1 = pos[2] + s.half * abs(az)
    s.omega = omega = carray(f64(a.qvel), 1)[0]
    i = s.recent_i
    recent[i, 0] = s.cx  # (its own probe circle excludes nothing: strict < in ``engage``)
    recent[i, 1] = s.cy
    p = s.probe
    s.near = (s.cx + p > s.lo[0] and s.cx - p < s.hi[0] and s.cy + p > s.lo[1] and s.cy - p < s.hi[1]
              and s.z1 > s.lo[2] and s.z0 < s.hi[2])
    s.feeding = 0
    if not s.near:
        return False
    # Velocity of the cutter centre: the body's spatial velocity (cvel, about the subtree
    # centre of mass of its tree's root) moved to the point.
    w = carray(f64(a.cvel), 6)
    o = carray(f64(a.com), 3)
    rx, ry, rz = pos[0] - o[0], pos[1] - o[1], pos[2] - o[2]
    s.vx = w[3] + w[1] * rz - w[2] * ry
    s.vy = w[4] + w[2] * rx - w[0] * rz
    s.speed = speed = math.hypot(s.vx, s.vy)
    s.cutting_on = abs(omega) >= s.min_speed and spindle[0].stalled == 0.0
    s.feeding = s.cutting_on and speed > 1e-6
    s.ex, s.ey = (s.vx / speed, s.vy / speed) if s.feeding else (0.0, 0.0)  # feed direction; e_n = z × e_f
    return bool(s.feeding)


@jit
def _implicit_feed(s: np.record, a: np.record, dt: float, ga: float, gb: float) -> float:
    """The end-of-step feed speed (>= 0) under the cutting force −v·(ga·e_f + gb·e_n): backward
    Euler with the cutter point's inverse inertia L = J M⁻¹ Jᵀ (J and M⁻¹Jᵀ in the work arrays)."""
    nv = a.nv
    jac = carray(f64(a.jac), (3, nv))
    minv = carray(f64(a.minv), (2, nv))
    qacc = carray(f64(a.qacc), nv)
    inv_l = np.zeros((2, 2))
    acc = np.zeros(2)
    for r in range(2):
        for k in range(nv):
            acc[r] += jac[r, k] * qacc[k]
            for c in range(2):
                inv_l[r, c] += jac[r, k] * minv[c, k]
    for r in range(2):  # last step's acceleration, less the cutting force's share
        acc[r] -= inv_l[r, 0] * s.applied[0] + inv_l[r, 1] * s.applied[1]
    ex, ey = s.ex, s.ey
    w = (s.vx + dt * acc[0]) * ex + (s.vy + dt * acc[1]) * ey
    g0, g1 = ga * ex - gb * ey, ga * ey + gb * ex
    gain = (ex * inv_l[0, 0] + ey * inv_l[1, 0]) * g0 + (ex * inv_l[0, 1] + ey * inv_l[1, 1]) * g1
    return max(w, 0.0) / (1.0 + dt * max(gain, 0.0))


@jit
def finish(material: np.ndarray, cut: np.ndarray, removed_at: np.ndarray, recent: np.ndarray, probes: np.ndarray,
           state: np.ndarray, ptr: np.ndarray, sums: np.ndarray, time: float, dt: float) -> None:
    """The second half of a step (see module doc); the outputs go to the record, added to ``sums``."""
    s, a, acc = state[0], ptr[0], sums[0]
    s.force[0] = s.force[1] = 0.0
    s.feed_force = s.normal_force = s.torque = s.mrr = s.power = s.depth = s.chip = 0.0
    s.cutting = s.blocked = 0
    s.feed_speed = 0.0
    omega, r = s.omega, s.radius
    fx = fy = torque = 0.0
    n_inside = 0
    if not s.near:
        s.block = 0
    else:
        n_inside, sx, sy = inside(material, material, removed_at, s.lo, s.h, s.cx, s.cy, s.z0, s.z1, r, False, 0.0)
        if s.feeding:
            s.depth = engage(material, recent, probes, s)
            sgn = 1.0 if omega > 0 else -1.0
            k_t = s.u
            k_r = k_t * s.radial
            # F = −(v_f/ω)·[K_r·(e_f I_cc + e_n I_cs) + s·K_t·(−e_f I_cs + e_n I_cc)], linear in
            # the feed speed: F = −v·(ga·e_f + gb·e_n), a stiff damper on a light tool, so the
            # feed speed is taken at the end of the step (backward Euler, ``_implicit_feed``).
            ga = (k_r * s.d_cc - sgn * k_t * s.d_cs) / abs(omega)
            gb = (k_r * s.d_cs + sgn * k_t * s.d_cc) / abs(omega)
            feed = _implicit_feed(s, a, dt, ga, gb)
            ex, ey = s.ex, s.ey
            fx = -feed * (ga * ex - gb * ey)
            fy = -feed * (ga * ey + gb * ex)
            c = feed / abs(omega)  # feed per radian: v_f/ω = c/(2π)
            area = r * s.d_c
            torque = c * k_t * area  # = u·v_f·A/ω
            s.force[0], s.force[1] = fx, fy
            s.feed_force = -(fx * ex + fy * ey)
            s.normal_force = -fx * ey + fy * ex
            s.torque, s.mrr, s.power = torque, feed * area, torque * abs(omega)
            s.chip = 2 * math.pi * c
            s.feed_speed = s.speed
            s.cutting = area > 0.0
        if n_inside and s.cutting_on:
            inside(material, cut, removed_at, s.lo, s.h, s.cx, s.cy, s.z0, s.z1, r, True, time)
            before = s.removed
            s.removed = before + n_inside * s.voxel
            s.dirty = 1
            s.cutting = 1
            if s.removed > before:
                acc.active = 1
        elif n_inside:
            # Uncut foam against a cutter that does not cut: a spring from where the cutter first
            # pressed in, along the direction into the material then (the overlap's centroid
            # seen from the axis), plus damping while pressing on.
            if s.block == 0:
                mx, my = sx / n_inside, sy / n_inside
                norm = math.hypot(mx, my)
                if norm < 1e-9:
                    mx, my, norm = s.vx, s.vy, max(s.speed, 1e-12)
                thickness = 0.0
                for k in range(material.shape[2]):
                    thickness += _layer_weights(s, k, s.z0, s.z1)
                thickness = max(thickness, s.h[2])
                s.block_pen = n_inside * s.voxel / (2 * r * thickness)  # equivalent flat-face penetration
                s.block_x, s.block_y, s.block_nx, s.block_ny, s.block = s.cx, s.cy, mx / norm, my / norm, 1
            nx_, ny_ = s.block_nx, s.block_ny
            delta = max((s.cx - s.block_x) * nx_ + (s.cy - s.block_y) * ny_ + s.block_pen, 0.0)
            magnitude = s.block_stiffness * delta + s.block_damping * max(s.vx * nx_ + s.vy * ny_, 0.0)
            fx, fy = -magnitude * nx_, -magnitude * ny_
            s.force[0], s.force[1] = fx, fy
            s.blocked = 1
            s.feed_speed = s.speed
            acc.blocked = 1
        if not n_inside or s.cutting_on:
            s.block = 0
    s.n_inside = n_inside
    s.recent_i = (s.recent_i + 1) % recent.shape[0]
    # The wrench (the force at the axis point, r × F about the body's centre of mass) replaces last step's.
    c3 = carray(f64(a.xipos), 3)
    rx, ry, rz = s.cx - c3[0], s.cy - c3[1], s.z_mid - c3[2]
    wrench = (fx, fy, 0.0, -rz * fy, rz * fx, rx * fy - ry * fx)
    xfrc = carray(f64(a.xfrc), 6)
    for q in range(6):
        xfrc[q] += wrench[q] - s.applied[q]
        s.applied[q] = wrench[q]
    # The spindle's load: it resists the spin but cannot reverse it within one step.
    load = -math.copysign(min(torque, s.inertia * abs(omega) / dt), omega) if torque > 0 else 0.0
    qfrc = carray(f64(a.qfrc), 1)
    qfrc[0] += load - s.torque_applied
    s.torque_applied = load
    acc.force[0] += s.force[0]
    acc.force[1] += s.force[1]
    acc.feed_force += s.feed_force
    acc.normal_force += s.normal_force
    acc.torque += s.torque
    acc.power += s.power
    acc.mrr += s.mrr
    acc.depth += s.depth
    acc.chip += s.chip
    acc.steps += 1


@jit
def tick(material: np.ndarray, cut: np.ndarray, removed_at: np.ndarray, recent: np.ndarray, probes: np.ndarray,
         state: np.ndarray, ptr: np.ndarray, sums: np.ndarray, spindle: np.ndarray, time: float, dt: float) -> None:
    """One step in one call: ``begin``, ``mj_jac``/``mj_solveM`` by address if needed, ``finish``."""
    if begin(recent, state, ptr, spindle):
        a = ptr[0]
        s = state[0]
        point = carray(f64(a.point), 3)
        point[0], point[1], point[2] = s.cx, s.cy, s.z_mid
        call_jac(a.jac_fn, a.model, a.data, a.jac, 0, a.point, a.body)
        call_solve(a.solve_fn, a.model, a.data, a.minv, a.jac, 2)
    finish(material, cut, removed_at, recent, probes, state, ptr, sums, time, dt)
