"""The control tick of one arm, compiled by numba: its only implementation.

``ArmController.update`` (``control.arm``) calls ``tick`` once per control tick with the
arm's constant law and its state, records with named fields (numpy structured dtypes
``law_dtype``, ``state_dtype``; numba reads their fields by name). The tick:

1. the commanded shape: plan + integrated correction + proportional share, each section
   bounded to its maximum bend (``commanded``);
2. closed loop: the weighted tool-pose error in the arm base frame, the PCC Jacobian
   (``kinematics_kernels.pose_jacobian``) and the damped-least-squares step
   Jᵀ(JJᵀ + λI)⁻¹e (``pose_step``), integrated into the correction with its bound per
   section (``integrate``), then the shape again;
3. tension keeping: each section's common-mode shortening integrated toward
   ``min_tension`` on its slackest cable (``keep_tension``);
4. the set-points: the shape's cable lengths less the pre-tension offset and the common
   mode (``set_points``).

Tested against the law written with vectorised numpy (``tests/test_control_kernels.py``) within
1e-12 m. ``plan_sample`` interpolates the plan at the tick's time (``controllers.plan_at``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..kinematics_kernels import cable_dtype, cable_lengths, jit, pose_dtype, pose_jacobian

Array = NDArray[np.float64]
Record = Any  # one record of a structured array (law_dtype / state_dtype): numba reads its fields as attributes

ROTATION_BEYOND_3_RAD = 1  # ``tick``'s status: give the rotation error (``kinematics.log_so3``) and call again


def law_dtype(n_sections: int, n_pairs: int) -> np.dtype:
    """Record of one arm's control law: geometry, mount, gains and bounds (fixed for a run)."""
    S, C = n_sections, 3 * n_sections
    return np.dtype([
        ("pose", pose_dtype(S)),
        ("cables", cable_dtype(S, n_pairs)),
        ("base_rot", np.float64, (3, 3)),  # the mount rotation's transpose: world -> arm base frame
        ("max_bend", np.float64, (S,)),  # rad, bound on each section's commanded bend
        ("offset", np.float64, (C,)),  # m, each cable's pre-tension offset T/k
        ("cable_section", np.int64, (C,)),  # section of each cable
        ("cable_kp", np.float64, (S,)),  # N/m, tension per metre of a section's common mode
        ("use_gain", np.bool_),  # integrate through the gain matrix (else the scalar outer_gain)
        ("gain", np.float64, (2 * S, 2 * S)),  # 1/s, the integral gain matrix
        ("outer_gain", np.float64),  # 1/s
        ("outer_proportional", np.float64),  # proportional share of the step
        ("orientation_weight", np.float64),  # m/rad
        ("damping", np.float64),  # m², damped-least-squares regulariser
        ("max_correction", np.float64),  # rad, bound on the correction per section
        ("roll_free", np.bool_),  # correct the tool point and axis only (5 task coordinates)
        ("min_tension", np.float64),  # N
        ("tension_gain", np.float64),  # 1/s
        ("max_extra_tension", np.float64),  # N
    ])


def state_dtype(n_sections: int) -> np.dtype:
    """Record of the controller's own state (updated in place by ``tick``)."""
    return np.dtype([
        ("correction", np.float64, (2 * n_sections,)),  # rad, integrated bending-coordinate correction
        ("proportional", np.float64, (2 * n_sections,)),  # rad, proportional share of the last step
        ("extra", np.float64, (n_sections,)),  # m, common-mode shortening per section (tension keeping)
        ("w", np.float64, (2 * n_sections,)),  # rad, the last commanded bending coordinates
    ])


@jit
def commanded(law: Record, state: Record, q_plan: Array) -> None:
    """``state.w``: the planned bend plus correction and proportional share, bend-limited per section."""
    c, pr, w = state.correction, state.proportional, state.w
    for k in range(law.max_bend.shape[0]):
        theta, phi = q_plan[2 * k], q_plan[2 * k + 1]
        u = theta * math.cos(phi) + c[2 * k] + pr[2 * k]
        v = theta * math.sin(phi) + c[2 * k + 1] + pr[2 * k + 1]
        bend, limit = math.hypot(u, v), law.max_bend[k]
        if bend > limit:
            u, v = u * limit / bend, v * limit / bend
        w[2 * k] = u
        w[2 * k + 1] = v


@jit
def rotation_error(target: Array, actual: Array, r: Array) -> bool:
    """log(R_target R_actualᵀ)^∨ into r (3,); False (r untouched) beyond 3 rad, where this formula loses accuracy.

    Only the skew part and the trace of E = R_t R_aᵀ are needed: E_ij = Σ_k t_ik a_jk.
    """
    e = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            e[i, j] = target[i, 0] * actual[j, 0] + target[i, 1] * actual[j, 1] + target[i, 2] * actual[j, 2]
    vx, vy, vz = 0.5 * (e[2, 1] - e[1, 2]), 0.5 * (e[0, 2] - e[2, 0]), 0.5 * (e[1, 0] - e[0, 1])
    sin = math.sqrt(vx * vx + vy * vy + vz * vz)
    angle = math.atan2(sin, 0.5 * (e[0, 0] + e[1, 1] + e[2, 2] - 1.0))
    if angle > 3.0:
        return False
    scale = angle / sin if sin > 1e-12 else 1.0
    r[0], r[1], r[2] = vx * scale, vy * scale, vz * scale
    return True


@jit
def pose_step(law: Record, w: Array, plan: Array, pos: Array, mat: Array, r: Array) -> Array:
    """The damped-least-squares step Jᵀ(JJᵀ + λI)⁻¹e in bending coordinates at shape ``w``.

    e: the tool-point error and ``orientation_weight`` × the rotation error ``r`` (world),
    both turned into the arm base frame; ``roll_free`` keeps the angular rows about the
    measured tool's x and y axes only. ``plan`` (4×4) the planned tool pose, ``pos``/``mat``
    the measured one (world).
    """
    b, ow, n = law.base_rot, law.orientation_weight, w.shape[0]
    R, p, Jflat = np.empty(9), np.empty(3), np.empty(6 * n)
    pose_jacobian(law.pose, w, R, p, Jflat, True)
    rows = np.empty(6)
    for i in range(3):
        rows[i] = b[i, 0] * (plan[0, 3] - pos[0]) + b[i, 1] * (plan[1, 3] - pos[1]) + b[i, 2] * (plan[2, 3] - pos[2])
        rows[3 + i] = ow * (b[i, 0] * r[0] + b[i, 1] * r[1] + b[i, 2] * r[2])
    m = 5 if law.roll_free else 6
    J, error = np.empty((m, n)), np.empty(m)
    for i in range(3):
        error[i] = rows[i]
        for c in range(n):
            J[i, c] = Jflat[i * n + c]
    if not law.roll_free:
        for i in range(3, 6):
            error[i] = rows[i]
            for c in range(n):
                J[i, c] = ow * Jflat[i * n + c]
    else:
        for j in range(2):  # the tool's x and y axes (columns of mat) in the base frame
            a0 = b[0, 0] * mat[0, j] + b[0, 1] * mat[1, j] + b[0, 2] * mat[2, j]
            a1 = b[1, 0] * mat[0, j] + b[1, 1] * mat[1, j] + b[1, 2] * mat[2, j]
            a2 = b[2, 0] * mat[0, j] + b[2, 1] * mat[1, j] + b[2, 2] * mat[2, j]
            error[3 + j] = a0 * rows[3] + a1 * rows[4] + a2 * rows[5]
            for c in range(n):
                J[3 + j, c] = ow * (a0 * Jflat[3 * n + c] + a1 * Jflat[4 * n + c] + a2 * Jflat[5 * n + c])
    A = np.empty((m, m))
    for i in range(m):
        for j in range(m):
            s = 0.0
            for c in range(n):
                s += J[i, c] * J[j, c]
            A[i, j] = s + (law.damping if i == j else 0.0)
    x = np.linalg.solve(A, error)
    step = np.zeros(n)
    for i in range(m):
        for c in range(n):
            step[c] += J[i, c] * x[i]
    return step


@jit
def integrate(law: Record, state: Record, step: Array, dt: float) -> None:
    """Integrate ``step`` into the correction (scalar gain or matrix), set the proportional share, bound per section."""
    c, n = state.correction, step.shape[0]
    if law.use_gain:
        for i in range(n):
            s = 0.0
            for j in range(n):
                s += law.gain[i, j] * step[j]
            c[i] += dt * s
    else:
        for i in range(n):
            c[i] += law.outer_gain * dt * step[i]
    for i in range(n):
        state.proportional[i] = law.outer_proportional * step[i]
    for k in range(n // 2):  # so that a transient cannot wind it up
        norm = math.hypot(c[2 * k], c[2 * k + 1])
        if norm > law.max_correction:
            f = law.max_correction / norm
            c[2 * k] *= f
            c[2 * k + 1] *= f


@jit
def keep_tension(law: Record, state: Record, tensions: Array, dt: float) -> None:
    """Integrate each section's common-mode shortening toward min_tension on its slackest cable, bounded.

    A section's three cables span its two bending coordinates plus one common mode:
    shortening all three together raises their tensions (by kp per metre) and leaves the
    bend, and so the pose loop, alone. A NaN tension propagates (as numpy's min would).
    """
    extra = state.extra
    for s in range(extra.shape[0]):
        t0, t1, t2 = tensions[3 * s], tensions[3 * s + 1], tensions[3 * s + 2]
        slackest = math.nan if (math.isnan(t0) or math.isnan(t1) or math.isnan(t2)) else min(t0, t1, t2)
        x = extra[s] + law.tension_gain * (law.min_tension - slackest) / law.cable_kp[s] * dt
        high = law.max_extra_tension / law.cable_kp[s]
        extra[s] = x if math.isnan(x) else min(max(x, 0.0), high)


@jit
def set_points(law: Record, state: Record, out: Array) -> None:
    """Cable lengths of the commanded shape less the pre-tension offset and the common mode."""
    cable_lengths(law.cables, state.w, out)
    for c in range(out.shape[0]):
        out[c] = out[c] - law.offset[c] - state.extra[law.cable_section[c]]


@jit
def tick(  # noqa: PLR0913
    laws: NDArray[np.void], states: NDArray[np.void], q_plan: Array, plan: Array, pos: Array, mat: Array, dt: float,
    closed: bool, keep: bool, tensions: Array, r: Array, have_r: bool, out: Array,
) -> int:
    """One control tick of the arm in the (1,) record arrays ``laws``/``states``: the set-points into ``out`` (C,); returns 0.

    ``closed``: integrate the pose error (``plan``, ``pos``, ``mat``) over ``dt``; ``keep``:
    tension keeping on the measured ``tensions``. ``have_r``: ``r`` holds the rotation
    error already; otherwise it is computed here and, beyond 3 rad, nothing changes and
    ``ROTATION_BEYOND_3_RAD`` is returned for the caller to give it (``kinematics.log_so3``).
    """
    law, state = laws[0], states[0]
    commanded(law, state, q_plan)
    if closed:
        if not have_r and not rotation_error(plan[:3, :3], mat, r):
            return ROTATION_BEYOND_3_RAD
        step = pose_step(law, state.w, plan, pos, mat, r)
        integrate(law, state, step, dt)
        commanded(law, state, q_plan)
    if keep:
        keep_tension(law, state, tensions, dt)
    set_points(law, state, out)
    return 0


@jit
def plan_sample(times: Array, t: float, q: Array, tcp: Array) -> tuple[Array, Array]:
    """(q, tcp) at time ``t`` from samples at uniform ``times``: (1 - f)·a + f·b, clamped at both ends."""
    n = times.shape[0]
    x = min(max((t - times[0]) / (times[1] - times[0]), 0.0), n - 1.0)
    i0 = min(int(x), n - 2)
    f = x - i0
    return (1.0 - f) * q[i0] + f * q[i0 + 1], (1.0 - f) * tcp[i0] + f * tcp[i0 + 1]
