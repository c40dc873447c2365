"""The compiled cable kernels (numba) and the per-data record they read: the only implementation of this physics.

* :func:`cable_pieces`: every piece's length, direction and local gradient from MuJoCo's
  own kinematics of the step (hole sites, hinge axes and anchors, body frames).
* :func:`native_cables`: the native cable path (``cable_path``): exact tendon lengths,
  Jacobians, velocities, actuator transmissions and tendon spring/damper forces.
* :func:`friction_forces`: capstan stick/slip friction in the holes (``friction``).

:data:`ROW` is the one declaration of what the passive callback hands the kernels for one
MjData: scalar flags and parameters, then for each array of :data:`ARRAYS` its address and
shape. ``passive.PassiveRuntime`` fills a row (checking every array against its dtype and
rank here); the kernels read the fields by name.
"""

from __future__ import annotations

import os

import numpy as np

from .jit import drop_stale_cache, jit
from .mujoco_native import view

F8, I8, I4, B1 = np.dtype(np.float64), np.dtype(np.int64), np.dtype(np.int32), np.dtype(np.bool_)

SCALARS: tuple[tuple[str, np.dtype], ...] = (
    ("data", I8), ("model", I8),  # addresses: the MjData this row belongs to, its MjModel
    ("native", I8), ("friction", I8),  # which hooks run (in this order)
    ("fwdact", I8),  # friction reads actuator forces: mj_fwdActuation first
    ("compute_pieces", I8),  # friction evaluates the pieces itself (no native hook did)
    ("base_hole", I8), ("mu", F8), ("presliding", F8),  # CableFrictionConfig
    ("err_native", I8), ("err_friction", I8),  # set when a kernel raised (a C callback cannot)
)
ARRAYS: tuple[tuple[str, np.dtype, int], ...] = (
    # the MjData's own buffers
    ("qvel", F8, 1), ("site_xpos", F8, 2), ("xmat", F8, 2), ("xaxis", F8, 2), ("xanchor", F8, 2),
    ("ten_length", F8, 1), ("ten_J", F8, 1), ("ten_velocity", F8, 1),
    ("actuator_length", F8, 1), ("actuator_velocity", F8, 1), ("actuator_moment", F8, 1), ("moment_rowadr", I4, 1),
    ("actuator_force", F8, 1), ("qfrc_spring", F8, 1), ("qfrc_damper", F8, 1), ("qfrc_passive", F8, 1),
    # the routing (cable_routing.CableRouting)
    ("piece_psite", I8, 1), ("piece_csite", I8, 1), ("piece_base", I8, 1), ("piece_seg", I8, 1),
    ("seg_jnt", I8, 2), ("seg_njnt", I8, 1), ("seg_ball", B1, 1), ("seg_body", I8, 1), ("seg_dofadr", I8, 1),
    ("cable_start", I8, 1), ("cable_end", I8, 1), ("tendon_ids", I8, 1),
    # what puts tension along each cable: its tendon's spring/damper, its actuators
    ("ten_stiffness", F8, 1), ("ten_damping", F8, 1), ("ten_spring", F8, 2),
    ("act_ids", I8, 1), ("act_owner", I8, 1), ("act_gear", F8, 1),
    # the native path's maps into MuJoCo's sparse rows
    ("piece_jadr", I8, 2), ("ten_rowadr", I8, 1), ("ten_rownnz", I8, 1), ("ten_colind", I8, 1),
    # per-data scratch (cable_routing.CablePieces) and friction state (friction.CableFriction)
    ("length", F8, 1), ("direction", F8, 2), ("grad", F8, 2),
    ("z", F8, 1), ("s_prev", F8, 1), ("initialised", B1, 1), ("tension", F8, 1), ("piece_tension", F8, 1),
    ("wrap", F8, 1),
)
ROW = np.dtype([*SCALARS, *((name, np.int64, (1 + ndim,)) for name, _, ndim in ARRAYS)], align=True)

# numba's cache of this module does not see edits to the intrinsics it inlines.
_HERE = os.path.dirname(os.path.abspath(__file__))
drop_stale_cache("cable_kernels", (__file__, os.path.join(_HERE, "mujoco_native.py")), ("cable_kernels",))


@jit
def cable_pieces(site_xpos, xmat, xaxis, xanchor, piece_psite, piece_csite, piece_seg, piece_base, seg_jnt, seg_njnt,
                 seg_ball, seg_body, length, direction, grad):  # fmt: skip
    """Per piece from MuJoCo's kinematics (position stage): length |x_c − x_p| (MuJoCo's arithmetic
    for a site-to-site tendon segment, so a spatial tendon's length bit for bit), the unit
    direction in the arm's base frame (cable friction's wrap angles) and
    ∂l/∂q_k = u·(a_k × (x_c − anchor_k)) for the dofs k of the segment the piece spans (a hinge:
    its axis; a ball: the child body's axes, its dofs being the angular velocity in that frame)."""
    for i in range(piece_seg.shape[0]):
        p, c = piece_psite[i], piece_csite[i]
        d0 = site_xpos[c, 0] - site_xpos[p, 0]
        d1 = site_xpos[c, 1] - site_xpos[p, 1]
        d2 = site_xpos[c, 2] - site_xpos[p, 2]
        n = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        length[i] = n
        if n < 1e-15:  # coincident holes (never in a built arm): MuJoCo's mju_normalize3 convention
            u0, u1, u2 = 1.0, 0.0, 0.0
        else:
            u0, u1, u2 = d0 / n, d1 / n, d2 / n
        b = piece_base[i]
        for r in range(3):
            direction[i, r] = xmat[b, r] * u0 + xmat[b, 3 + r] * u1 + xmat[b, 6 + r] * u2
        g = piece_seg[i]
        body = seg_body[g]
        for k in range(3):
            if k < seg_njnt[g]:
                j = seg_jnt[g, k]
                r0 = site_xpos[c, 0] - xanchor[j, 0]
                r1 = site_xpos[c, 1] - xanchor[j, 1]
                r2 = site_xpos[c, 2] - xanchor[j, 2]
                if seg_ball[g]:
                    a0, a1, a2 = xmat[body, k], xmat[body, 3 + k], xmat[body, 6 + k]
                else:
                    a0, a1, a2 = xaxis[j, 0], xaxis[j, 1], xaxis[j, 2]
                grad[i, k] = u0 * (a1 * r2 - a2 * r1) + u1 * (a2 * r0 - a0 * r2) + u2 * (a0 * r1 - a1 * r0)
            else:
                grad[i, k] = 0.0


@jit
def _pieces_of(r):
    """:func:`cable_pieces` on the arrays of the row ``r``."""
    cable_pieces(view(r.site_xpos, F8), view(r.xmat, F8), view(r.xaxis, F8), view(r.xanchor, F8),
                 view(r.piece_psite, I8), view(r.piece_csite, I8), view(r.piece_seg, I8), view(r.piece_base, I8),
                 view(r.seg_jnt, I8), view(r.seg_njnt, I8), view(r.seg_ball, B1), view(r.seg_body, I8),
                 view(r.length, F8), view(r.direction, F8), view(r.grad, F8))


@jit
def native_cables(rows):
    """The native cable path of the data of ``rows[0]``: the pieces, then each cable's ``ten_length``,
    ``ten_J`` (the scatter of its pieces' gradients), ``ten_velocity``, its actuators' length,
    velocity and moment (gear × the tendon's), and its tendon spring (dead band between the two
    spring lengths) and damper added to ``qfrc_spring``/``qfrc_damper``/``qfrc_passive``."""
    r = rows[0]
    _pieces_of(r)
    qvel, length, grad = view(r.qvel, F8), view(r.length, F8), view(r.grad, F8)
    piece_seg, seg_njnt, piece_jadr = view(r.piece_seg, I8), view(r.seg_njnt, I8), view(r.piece_jadr, I8)
    cable_start, cable_end, tendon_ids = view(r.cable_start, I8), view(r.cable_end, I8), view(r.tendon_ids, I8)
    ten_rowadr, ten_rownnz, ten_colind = view(r.ten_rowadr, I8), view(r.ten_rownnz, I8), view(r.ten_colind, I8)
    ten_stiffness, ten_damping, ten_spring = view(r.ten_stiffness, F8), view(r.ten_damping, F8), view(r.ten_spring, F8)
    ten_length, ten_J, ten_velocity = view(r.ten_length, F8), view(r.ten_J, F8), view(r.ten_velocity, F8)
    qfrc_spring, qfrc_damper, qfrc_passive = view(r.qfrc_spring, F8), view(r.qfrc_damper, F8), view(r.qfrc_passive, F8)
    for c in range(cable_start.shape[0]):
        t = tendon_ids[c]
        adr, nnz = ten_rowadr[t], ten_rownnz[t]
        for j in range(nnz):
            ten_J[adr + j] = 0.0
        L = 0.0
        for i in range(cable_start[c], cable_end[c]):
            L += length[i]
            for k in range(seg_njnt[piece_seg[i]]):
                ten_J[piece_jadr[i, k]] += grad[i, k]
        v = 0.0
        for j in range(nnz):
            v += ten_J[adr + j] * qvel[ten_colind[adr + j]]
        ten_length[t] = L
        ten_velocity[t] = v
        spring = 0.0
        if L > ten_spring[c, 1]:
            spring = -ten_stiffness[c] * (L - ten_spring[c, 1])
        elif L < ten_spring[c, 0]:
            spring = -ten_stiffness[c] * (L - ten_spring[c, 0])
        damper = -ten_damping[c] * v
        for j in range(nnz):
            dof = ten_colind[adr + j]
            jv = ten_J[adr + j]
            qfrc_spring[dof] += jv * spring
            qfrc_damper[dof] += jv * damper
            qfrc_passive[dof] += jv * spring + jv * damper
    act_ids, act_owner, act_gear = view(r.act_ids, I8), view(r.act_owner, I8), view(r.act_gear, F8)
    actuator_length, actuator_velocity = view(r.actuator_length, F8), view(r.actuator_velocity, F8)
    actuator_moment, moment_rowadr = view(r.actuator_moment, F8), view(r.moment_rowadr, I4)
    for a in range(act_ids.shape[0]):
        t = tendon_ids[act_owner[a]]
        adr, nnz = ten_rowadr[t], ten_rownnz[t]
        gear = act_gear[a]
        act = act_ids[a]
        actuator_length[act] = gear * ten_length[t]
        actuator_velocity[act] = gear * ten_velocity[t]
        madr = moment_rowadr[act]
        for j in range(nnz):
            actuator_moment[madr + j] = gear * ten_J[adr + j]


@jit
def friction_forces(rows):
    """Update the stick/slip states of the data of ``rows[0]`` and add the capstan correction to its ``qfrc_passive``.

    T (``tension``, written) is the uniform tension MuJoCo applies along each tendon: minus
    its actuators' forces plus its spring (dead band between the two spring lengths) and
    damper. Hole j of a cable (j = 0: base plate, j ≥ 1: the disk between piece j and j+1)
    has wrap β_j, sliding coordinate s_j = Σ_{i>j} l_i (the cable length beyond it) and
    state z_j; piece tensions T_1 = T·e^(μβ_0 z_0), T_{j+1} = T_j·e^(μβ_j z_j).
    """
    r = rows[0]
    mu, presliding, base_hole = r.mu, r.presliding, r.base_hole != 0
    cable_start, cable_end, tendon_ids = view(r.cable_start, I8), view(r.cable_end, I8), view(r.tendon_ids, I8)
    ten_length, ten_velocity = view(r.ten_length, F8), view(r.ten_velocity, F8)
    ten_stiffness, ten_damping, ten_spring = view(r.ten_stiffness, F8), view(r.ten_damping, F8), view(r.ten_spring, F8)
    act_ids, act_owner, actuator_force = view(r.act_ids, I8), view(r.act_owner, I8), view(r.actuator_force, F8)
    tension = view(r.tension, F8)
    for c in range(cable_start.shape[0]):
        t = tendon_ids[c]
        L = ten_length[t]
        stretch = 0.0
        if L > ten_spring[c, 1]:
            stretch = L - ten_spring[c, 1]
        elif L < ten_spring[c, 0]:
            stretch = L - ten_spring[c, 0]
        tension[c] = ten_stiffness[c] * stretch + ten_damping[c] * ten_velocity[t]
    for j in range(act_ids.shape[0]):
        tension[act_owner[j]] -= actuator_force[act_ids[j]]
    if r.compute_pieces != 0:
        _pieces_of(r)
    length, direction, grad = view(r.length, F8), view(r.direction, F8), view(r.grad, F8)
    piece_seg, seg_njnt, seg_dofadr = view(r.piece_seg, I8), view(r.seg_njnt, I8), view(r.seg_dofadr, I8)
    z, s_prev, initialised = view(r.z, F8), view(r.s_prev, F8), view(r.initialised, B1)
    piece_tension, wrap, qfrc = view(r.piece_tension, F8), view(r.wrap, F8), view(r.qfrc_passive, F8)
    for c in range(cable_start.shape[0]):
        a, b = cable_start[c], cable_end[c]
        for j in range(b - a):  # wraps: hole j sits before piece a+j
            i = a + j
            if j == 0:
                cosb = direction[i, 2] if base_hole else 1.0  # the cable arrives along the base z
            else:
                cosb = 0.0
                for k in range(3):
                    cosb += direction[i - 1, k] * direction[i, k]
            cosb = min(1.0, max(-1.0, cosb))
            wrap[i] = np.arccos(cosb)
        # sliding coordinates and the exact Dahl update
        s = 0.0
        for i in range(b - 1, a - 1, -1):
            s += length[i]  # cable length beyond hole (i − a)
            if initialised[c]:
                ds = s - s_prev[i]
                if ds != 0.0:
                    sg = 1.0 if ds > 0.0 else -1.0
                    z[i] = sg + (z[i] - sg) * np.exp(-abs(ds) / presliding)
            else:
                z[i] = 0.0
            s_prev[i] = s
        initialised[c] = True
        T = tension[c]
        t_piece = T
        for i in range(a, b):
            t_piece *= np.exp(mu * wrap[i] * z[i])
            piece_tension[i] = t_piece
            if T > 0.0:
                dT = t_piece - T
                g = piece_seg[i]
                for k in range(seg_njnt[g]):
                    qfrc[seg_dofadr[g] + k] -= dT * grad[i, k]
            else:
                piece_tension[i] = T  # a slack (or pushed) cable carries no friction
