"""Cable friction in the disk holes: capstan tension loss with stick/slip (issue 13).

Each cable of the generated model is ONE MuJoCo spatial tendon through a site at its hole
on every disk, so MuJoCo transmits one uniform tension T along it (actuator force plus
the tendon's own spring/damper). A real cable loses tension at every hole it slides
through: over a hole where it turns by the wrap angle β, the capstan relation
(Euler–Eytelwein) bounds the tension ratio of the two pieces,

    e^(−μβ) ≤ T_distal / T_proximal ≤ e^(+μβ),

the lower bound reached while the cable is reeled in (slides toward the motor), the upper
one while it pays out, anything between while it sticks. This module adds that physics to
a compiled model through MuJoCo's passive-force callback, without touching the model:

* **Cable kernel** (:func:`cable_pieces`, numba): from the joint coordinates, the length,
  direction and gradient w.r.t. the local joint velocities of every per-segment piece
  l = t + R(s + h) − h of every cable (SPEC §2). A piece's length depends only on the
  joints of the segment it spans, so each gradient has ≤ 3 entries. Joint types: ball,
  any chain of 1–3 hinges sharing one anchor (``hinge_pair``, a twist joint). The same
  output would let fixed tendons replace the spatial ones (length + sparse Jacobian).
* **Stick/slip** (Dahl model, normalised): per hole a state z ∈ [−1, 1] with
  dz/ds = (1 − z·sgn ds)/δ over the cable's sliding distance s through the hole (the
  change of its length beyond the hole); the piece ratio is e^(μβz). It is integrated
  exactly (z → sgn + (z − sgn)e^(−|Δs|/δ)) from the positions at each evaluation, so the
  state is rate-independent, idempotent under repeated ``mj_forward`` and unconditionally
  stable. δ (``presliding``) is the sliding distance over which friction builds up after
  a reversal: the stick band, a numerical regularisation of ideal Coulomb stick.
* **Force**: MuJoCo already applies −T_mj·∂l/∂q for the uniform tension; the callback adds
  −Σ_i (T_i − T_mj)·∂l_i/∂q over the pieces, with T_i = T_mj·Π_{holes before i} e^(μβz).

μ = 0 installs nothing: the model runs exactly as without this module.
"""

from __future__ import annotations

import copy
import itertools
import os
import re
import sys
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..configio import require_range
from .jit import jit_in_place, sigint_deferred

# *Assumed* default μ: a steel rope sliding in the holes of 3D-printed polymer disks (the
# prototype's disks are printed, Table 1 of the paper). Dry steel on nylon/PLA/PTFE lies
# at μ ≈ 0.05–0.25 in engineering friction tables; 0.15 is the middle of the 0.1–0.2 range
# the issue names for steel rope in polymer or PTFE-lined holes. Not measured on the robot.
DEFAULT_MU = 0.15
# Stick band: 1 mm of sliding builds friction from zero to full after a reversal. A
# numerical regularisation of ideal stick (a steel rope's own stretch over one 15–21 mm
# piece at a ~1 N friction step is ~1 µm). The presliding stiffness μβT/δ enters the
# explicit passive force, so δ must keep it inside the 4 ms step's stability limit: with
# the gripper holding the welded sample (the jaws reaching the grasp since the preloaded
# jaw springs) δ = 0.2 mm rang the gripper arm's cables at 18 Hz, 9 N peak-to-peak above
# 10 Hz and 6 solver iterations per step; δ = 1 mm: 0.00 N and 1 iteration, as at 2 ms
# (`python scripts/tension_chatter.py hold --variants default,presliding0.2mm,dt2ms`).
# The capstan does not depend on δ (< 0.1 % from 0.05 to 0.2 mm, rows `continuum-sim
# validate --only capstan`); 1 mm is 4 % of a section's 24 mm cable stroke.
DEFAULT_PRESLIDING = 1.0e-3

CABLE_TENDON_PATTERN = r"(^|/)cable_\d+_\d+$"


@dataclass(frozen=True)
class CableFrictionConfig:
    """Friction of the cables in the disk holes (μ = 0: frictionless, nothing installed)."""

    mu: float = DEFAULT_MU  # Coulomb coefficient, steel rope in printed-polymer holes (*assumed*)
    presliding: float = DEFAULT_PRESLIDING  # m, Dahl stick band (numerical regularisation of stick)
    base_hole: bool = True  # friction also where the cable enters the base plate (arriving along the base z)

    def __post_init__(self) -> None:
        require_range("mu", self.mu, 0.0, 1.0, low_inclusive=True)
        require_range("presliding", self.presliding, 1e-7, 1e-2, low_inclusive=True)
        if not isinstance(self.base_hole, bool):
            from ..configio import ConfigError

            raise ConfigError(
                "base_hole", f"must be true or false (got {self.base_hole!r})"
            )


# ------------------------------------------------------------------------ numba kernels

def _axis_angle(axis: np.ndarray, angle: float, R: np.ndarray) -> None:
    """R = rotation of ``angle`` about the unit ``axis`` (Rodrigues)."""
    c, s = np.cos(angle), np.sin(angle)
    x, y, z = axis[0], axis[1], axis[2]
    C = 1.0 - c
    R[0, 0] = c + x * x * C
    R[0, 1] = x * y * C - z * s
    R[0, 2] = x * z * C + y * s
    R[1, 0] = y * x * C + z * s
    R[1, 1] = c + y * y * C
    R[1, 2] = y * z * C - x * s
    R[2, 0] = z * x * C - y * s
    R[2, 1] = z * y * C + x * s
    R[2, 2] = c + z * z * C


def _quat_mat(qpos: np.ndarray, a: int, R: np.ndarray) -> None:
    """R = rotation of the (w, x, y, z) quaternion at qpos[a:a+4] (normalised, as MuJoCo does)."""
    w, x, y, z = qpos[a], qpos[a + 1], qpos[a + 2], qpos[a + 3]
    n = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    R[0, 0] = 1 - 2 * (y * y + z * z)
    R[0, 1] = 2 * (x * y - w * z)
    R[0, 2] = 2 * (x * z + w * y)
    R[1, 0] = 2 * (x * y + w * z)
    R[1, 1] = 1 - 2 * (x * x + z * z)
    R[1, 2] = 2 * (y * z - w * x)
    R[2, 0] = 2 * (x * z - w * y)
    R[2, 1] = 2 * (y * z + w * x)
    R[2, 2] = 1 - 2 * (x * x + y * y)


def _matmul3(A: np.ndarray, B: np.ndarray, out: np.ndarray) -> None:
    """out = A·B for 3×3 (out must not alias A or B)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


def _segment_rotations(
    qpos, seg_ball, seg_njnt, seg_qadr, seg_qref, seg_axes, seg_bmat, seg_R, seg_w
):
    """Per segment: R = Rb·Rj (child in parent frame) and each dof's axis w_k in the parent frame.

    Hinge chain Rj = E1·E2·E3 (MuJoCo applies a body's joints in order, each about its
    axis in the body frame); the velocity of dof k turns the child about Rb·E1..E(k−1)·a_k.
    Ball: qvel is the angular velocity in the child frame, so w_k = Rb·Rj·e_k.
    """
    E = np.empty((3, 3))
    acc = np.empty((3, 3))
    tmp = np.empty((3, 3))
    for g in range(seg_ball.shape[0]):
        Rb = seg_bmat[g]
        if seg_ball[g]:
            _quat_mat(qpos, seg_qadr[g, 0], E)
            _matmul3(Rb, E, seg_R[g])
            for k in range(3):
                for r in range(3):
                    seg_w[g, k, r] = seg_R[g, r, k]
        else:
            acc[:, :] = Rb
            for k in range(seg_njnt[g]):
                for r in range(3):
                    seg_w[g, k, r] = (
                        acc[r, 0] * seg_axes[g, k, 0]
                        + acc[r, 1] * seg_axes[g, k, 1]
                        + acc[r, 2] * seg_axes[g, k, 2]
                    )
                _axis_angle(seg_axes[g, k], qpos[seg_qadr[g, k]] - seg_qref[g, k], E)
                _matmul3(acc, E, tmp)
                acc[:, :] = tmp
            seg_R[g, :, :] = acc


def _cable_pieces(
    qpos, seg_ball, seg_njnt, seg_qadr, seg_qref, seg_axes, seg_bpos, seg_bmat, seg_jpos,
    piece_seg, piece_parent, piece_child, seg_R, seg_w, length, direction, grad,
):  # fmt: skip
    """Lengths, unit directions (parent frame) and local-dof gradients of every piece."""
    _segment_rotations(
        qpos, seg_ball, seg_njnt, seg_qadr, seg_qref, seg_axes, seg_bmat, seg_R, seg_w
    )
    arm = np.empty(3)
    vec = np.empty(3)
    for i in range(piece_seg.shape[0]):
        g = piece_seg[i]
        Rb = seg_bmat[g]
        R = seg_R[g]
        jp = seg_jpos[g]
        for r in range(3):  # child hole from the joint anchor, parent frame
            arm[r] = (
                R[r, 0] * (piece_child[i, 0] - jp[0])
                + R[r, 1] * (piece_child[i, 1] - jp[1])
                + R[r, 2] * (piece_child[i, 2] - jp[2])
            )
        for r in range(3):
            vec[r] = (
                seg_bpos[g, r]
                + Rb[r, 0] * jp[0]
                + Rb[r, 1] * jp[1]
                + Rb[r, 2] * jp[2]
                + arm[r]
                - piece_parent[i, r]
            )
        n = np.sqrt(vec[0] * vec[0] + vec[1] * vec[1] + vec[2] * vec[2])
        length[i] = n
        u0, u1, u2 = vec[0] / n, vec[1] / n, vec[2] / n
        direction[i, 0] = u0
        direction[i, 1] = u1
        direction[i, 2] = u2
        ndof = 3 if seg_ball[g] else seg_njnt[g]
        for k in range(3):
            if k < ndof:
                w0, w1, w2 = seg_w[g, k, 0], seg_w[g, k, 1], seg_w[g, k, 2]
                d0 = w1 * arm[2] - w2 * arm[1]
                d1 = w2 * arm[0] - w0 * arm[2]
                d2 = w0 * arm[1] - w1 * arm[0]
                grad[i, k] = u0 * d0 + u1 * d1 + u2 * d2
            else:
                grad[i, k] = 0.0


def _friction_forces(
    qpos, seg_ball, seg_njnt, seg_qadr, seg_qref, seg_axes, seg_bpos, seg_bmat, seg_jpos, seg_dofadr,
    piece_seg, piece_parent, piece_child, cable_start, cable_end, tendon_ids,
    act_ids, act_owner, actuator_force, ten_stiffness, ten_damping, ten_spring, ten_length, ten_velocity,
    mu, presliding, base_hole, z, s_prev, initialised, tension,
    seg_R, seg_w, length, direction, grad, piece_tension, wrap, qfrc, compute_pieces,
):  # fmt: skip
    """Update the stick/slip states and add the capstan correction to ``qfrc``.

    T (``tension``, written) is the uniform tension MuJoCo applies along each tendon: minus
    its actuators' forces plus its spring (dead band between the two spring lengths) and
    damper. Hole j of a cable (j = 0: base plate, j ≥ 1: the disk between piece j and j+1)
    has wrap β_j, sliding coordinate s_j = Σ_{i>j} l_i (the cable length beyond it) and
    state z_j; piece tensions T_1 = T·e^(μβ_0 z_0), T_{j+1} = T_j·e^(μβ_j z_j).
    ``compute_pieces`` False: the pieces (length, direction, grad) of this qpos are already
    there (the native cable path evaluated them in the same callback).
    """
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
    if compute_pieces:
        _cable_pieces(
            qpos, seg_ball, seg_njnt, seg_qadr, seg_qref, seg_axes, seg_bpos, seg_bmat, seg_jpos,
            piece_seg, piece_parent, piece_child, seg_R, seg_w, length, direction, grad,
        )  # fmt: skip
    for c in range(cable_start.shape[0]):
        a, b = cable_start[c], cable_end[c]
        # wraps: hole j sits before piece a+j
        for j in range(b - a):
            i = a + j
            if j == 0:
                cosb = (
                    direction[i, 2] if base_hole else 1.0
                )  # cable arrives along the base z
            else:
                # previous piece (parent frame of its segment) vs this piece rotated into that frame
                R = seg_R[piece_seg[i - 1]]
                cosb = 0.0
                for r in range(3):
                    cosb += direction[i - 1, r] * (
                        R[r, 0] * direction[i, 0]
                        + R[r, 1] * direction[i, 1]
                        + R[r, 2] * direction[i, 2]
                    )
            cosb = min(1.0, max(-1.0, cosb))
            wrap[i] = np.arccos(cosb)
        # sliding coordinates and exact Dahl update
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
                ndof = 3 if seg_ball[g] else seg_njnt[g]
                for k in range(ndof):
                    qfrc[seg_dofadr[g] + k] -= dT * grad[i, k]
            else:
                piece_tension[i] = T  # a slack (or pushed) cable carries no friction


_KERNELS: dict[str, Any] = {}


def kernels() -> dict[str, Any]:
    """The numba-compiled kernels (compiled, or loaded from numba's cache, on first use).

    Lazy: ``ModelOptions`` imports this module for its config, and importing numba (let
    alone compiling) should cost nothing to runs without friction. The helpers are
    rebound to their jitted versions so the kernels call them in nopython mode.
    """
    if not _KERNELS:
        jit_in_place(globals(), ("_axis_angle", "_quat_mat", "_matmul3", "_segment_rotations", "_cable_pieces",
                                 "_friction_forces"))
        _KERNELS.update(cable_pieces=_cable_pieces, friction_forces=_friction_forces)
    return _KERNELS


# ----------------------------------------------------------------- routing from a model
@dataclass(frozen=True)
class CableRouting:
    """Static description of the cables of a compiled model, read from its tendons.

    Segment arrays (one entry per disk body a piece ends on): ``ball`` flag, hinge count,
    qpos addresses, reference angles, axes (child frame), body offset ``bpos``/``bmat`` in
    the parent frame, joint anchor ``jpos`` (child frame), first dof address. Piece arrays:
    segment index, parent hole (parent frame), child hole (child frame). Cable c owns the
    pieces ``cable_start[c]:cable_end[c]``, base to anchor.
    """

    tendon_ids: np.ndarray
    names: tuple[str, ...]
    seg_body: np.ndarray
    seg_ball: np.ndarray
    seg_njnt: np.ndarray
    seg_qadr: np.ndarray
    seg_qref: np.ndarray
    seg_axes: np.ndarray
    seg_bpos: np.ndarray
    seg_bmat: np.ndarray
    seg_jpos: np.ndarray
    seg_dofadr: np.ndarray
    piece_seg: np.ndarray
    piece_parent: np.ndarray
    piece_child: np.ndarray
    cable_start: np.ndarray
    cable_end: np.ndarray

    @property
    def n_pieces(self) -> int:
        return int(self.piece_seg.shape[0])


def cable_tendons(model, pattern: str = CABLE_TENDON_PATTERN) -> np.ndarray:
    """Ids of the spatial tendons whose names match ``pattern`` (the arm cables)."""
    import mujoco

    rx = re.compile(pattern)
    ids = [t for t in range(model.ntendon) if rx.search(model.tendon(t).name or "")]
    for t in ids:
        adr = model.tendon_adr[t]
        if any(
            model.wrap_type[adr + k] != mujoco.mjtWrap.mjWRAP_SITE
            for k in range(model.tendon_num[t])
        ):
            raise ValueError(
                f"tendon {model.tendon(t).name!r} is not a site-only spatial tendon"
            )
    return np.array(ids, dtype=np.int64)


def cable_routing(model, tendon_ids: np.ndarray | None = None) -> CableRouting:
    """Read the cable routing (sites, disks, joints) of ``model`` for the kernels.

    Each consecutive pair of a tendon's sites must sit on a parent disk and its child,
    joined by one ball joint or 1–3 hinges sharing one anchor (what the arm builder makes).
    """

    if tendon_ids is None:
        tendon_ids = cable_tendons(model)
    tendon_ids = np.asarray(tendon_ids, dtype=np.int64)
    seg_index: dict[int, int] = {}
    seg: dict[str, list] = {
        k: []
        for k in (
            "body",
            "ball",
            "njnt",
            "qadr",
            "qref",
            "axes",
            "bpos",
            "bmat",
            "jpos",
            "dofadr",
        )
    }
    piece_seg: list[int] = []
    piece_parent: list[np.ndarray] = []
    piece_child: list[np.ndarray] = []
    start: list[int] = []
    end: list[int] = []
    for t in tendon_ids:
        name = model.tendon(int(t)).name
        adr, num = int(model.tendon_adr[t]), int(model.tendon_num[t])
        sites = [int(model.wrap_objid[adr + k]) for k in range(num)]
        start.append(len(piece_seg))
        for parent_site, child_site in itertools.pairwise(sites):
            body = int(model.site_bodyid[child_site])
            if int(model.body_parentid[body]) != int(model.site_bodyid[parent_site]):
                raise ValueError(
                    f"tendon {name!r}: sites {parent_site} and {child_site} are not on a parent and its child"
                )
            if body not in seg_index:
                seg_index[body] = len(seg["body"])
                _add_segment(model, body, seg, name)
            piece_seg.append(seg_index[body])
            piece_parent.append(np.array(model.site_pos[parent_site], dtype=float))
            piece_child.append(np.array(model.site_pos[child_site], dtype=float))
        end.append(len(piece_seg))
        if end[-1] == start[-1]:
            raise ValueError(f"tendon {name!r} has fewer than two sites")
    return CableRouting(
        tendon_ids=tendon_ids,
        names=tuple(model.tendon(int(t)).name for t in tendon_ids),
        seg_body=np.array(seg["body"], dtype=np.int64),
        seg_ball=np.array(seg["ball"], dtype=np.bool_),
        seg_njnt=np.array(seg["njnt"], dtype=np.int64),
        seg_qadr=np.array(seg["qadr"], dtype=np.int64).reshape(-1, 3),
        seg_qref=np.array(seg["qref"], dtype=float).reshape(-1, 3),
        seg_axes=np.array(seg["axes"], dtype=float).reshape(-1, 3, 3),
        seg_bpos=np.array(seg["bpos"], dtype=float).reshape(-1, 3),
        seg_bmat=np.array(seg["bmat"], dtype=float).reshape(-1, 3, 3),
        seg_jpos=np.array(seg["jpos"], dtype=float).reshape(-1, 3),
        seg_dofadr=np.array(seg["dofadr"], dtype=np.int64),
        piece_seg=np.array(piece_seg, dtype=np.int64),
        piece_parent=np.array(piece_parent, dtype=float).reshape(-1, 3),
        piece_child=np.array(piece_child, dtype=float).reshape(-1, 3),
        cable_start=np.array(start, dtype=np.int64),
        cable_end=np.array(end, dtype=np.int64),
    )


def _add_segment(model, body: int, seg: dict[str, list], tendon: str) -> None:
    import mujoco

    first, count = int(model.body_jntadr[body]), int(model.body_jntnum[body])
    types = [int(model.jnt_type[first + k]) for k in range(count)]
    ball = types == [int(mujoco.mjtJoint.mjJNT_BALL)]
    if not ball and not (
        1 <= count <= 3 and all(t == int(mujoco.mjtJoint.mjJNT_HINGE) for t in types)
    ):
        raise ValueError(
            f"tendon {tendon!r}: body {model.body(body).name!r} needs one ball joint or 1-3 hinges"
        )
    jpos = np.array(model.jnt_pos[first], dtype=float)
    if any(not np.allclose(model.jnt_pos[first + k], jpos) for k in range(count)):
        raise ValueError(
            f"body {model.body(body).name!r}: its hinges must share one anchor"
        )
    qadr = np.zeros(3, dtype=np.int64)
    qref = np.zeros(3)
    axes = np.zeros((3, 3))
    for k in range(1 if ball else count):
        j = first + k
        qadr[k] = model.jnt_qposadr[j]
        if not ball:
            qref[k] = model.qpos0[model.jnt_qposadr[j]]
            axes[k] = model.jnt_axis[j] / np.linalg.norm(model.jnt_axis[j])
    bmat = np.zeros(9)
    mujoco.mju_quat2Mat(bmat, np.array(model.body_quat[body], dtype=float))
    seg["body"].append(body)
    seg["ball"].append(ball)
    seg["njnt"].append(3 if ball else count)
    seg["qadr"].append(qadr)
    seg["qref"].append(qref)
    seg["axes"].append(axes)
    seg["bpos"].append(np.array(model.body_pos[body], dtype=float))
    seg["bmat"].append(bmat.reshape(3, 3))
    seg["jpos"].append(jpos)
    seg["dofadr"].append(int(model.jnt_dofadr[first]))


class CableKernel:
    """Piece lengths and local gradients of all cables of a model, from its joint coordinates.

    ``evaluate(qpos)`` fills ``length`` (P,), ``direction`` (P, 3, parent-disk frame) and
    ``grad`` (P, 3): ∂l_i/∂(local dof k) for the ≤ 3 dofs of the segment piece i spans
    (dof address ``routing.seg_dofadr[routing.piece_seg[i]] + k``). A cable's length is
    the sum of its pieces; its Jacobian row is the scatter of its pieces' gradients.
    """

    def __init__(self, model, tendon_ids: np.ndarray | None = None) -> None:
        self.routing = cable_routing(model, tendon_ids)
        r = self.routing
        n_seg, n_pieces = r.seg_body.shape[0], r.n_pieces
        self.seg_R = np.zeros((n_seg, 3, 3))
        self.seg_w = np.zeros((n_seg, 3, 3))
        self.length = np.zeros(n_pieces)
        self.direction = np.zeros((n_pieces, 3))
        self.grad = np.zeros((n_pieces, 3))
        self._fn = kernels()["cable_pieces"]

    def for_data(self) -> CableKernel:
        """A kernel sharing this one's routing with scratch of its own (copies of ``seg_R``, new
        ``seg_w``/``length``/``direction``/``grad``): the kernels run without the GIL, so two
        datas of one model stepped in two threads must not write the same scratch."""
        other = copy.copy(self)
        other.seg_R = self.seg_R.copy()
        other.seg_w = np.zeros_like(self.seg_w)
        other.length = np.zeros_like(self.length)
        other.direction = np.zeros_like(self.direction)
        other.grad = np.zeros_like(self.grad)
        return other

    def evaluate(self, qpos: np.ndarray) -> None:
        r = self.routing
        self._fn(
            np.ascontiguousarray(qpos, dtype=float), r.seg_ball, r.seg_njnt, r.seg_qadr, r.seg_qref, r.seg_axes,
            r.seg_bpos, r.seg_bmat, r.seg_jpos, r.piece_seg, r.piece_parent, r.piece_child,
            self.seg_R, self.seg_w, self.length, self.direction, self.grad,
        )  # fmt: skip

    def cable_lengths(self) -> np.ndarray:
        """(C,) total length of each cable at the last evaluation."""
        r = self.routing
        return np.array(
            [self.length[a:b].sum() for a, b in zip(r.cable_start, r.cable_end)]
        )

    def cable_jacobian(self, nv: int) -> np.ndarray:
        """(C, nv) dense ∂L_c/∂qvel at the last evaluation (what MuJoCo's ten_J holds)."""
        r = self.routing
        J = np.zeros((len(r.cable_start), nv))
        for c, (a, b) in enumerate(zip(r.cable_start, r.cable_end)):
            for i in range(a, b):
                g = r.piece_seg[i]
                for k in range(3 if r.seg_ball[g] else r.seg_njnt[g]):
                    J[c, r.seg_dofadr[g] + k] += self.grad[i, k]
        return J


# ------------------------------------------------------------------- the passive hook
class TableHook:
    """What a passive hook needs to be run by the compiled callback's table (``native_callback``):
    ``error`` also reads the table's flags, and replacing ``apply`` on the instance (tests) moves
    the hook to the Python callback until the class's own method is back. Subclasses set
    ``table_kind``, ``_key`` (their data's address) and ``_error``, and define ``table_arrays``."""

    table_kind = ""
    _key: int
    _error: BaseException | None

    @property
    def error(self) -> BaseException | None:
        """The first error the passive callback met in this hook (None: none)."""
        if self._error is None and _SLOTS:
            _table_error(self)
        return self._error

    @error.setter
    def error(self, value: BaseException | None) -> None:
        self._error = value

    def __setattr__(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)
        if name == "apply":  # a replaced apply (tests) only runs through the Python callback
            _resync(self)

    def __delattr__(self, name: str) -> None:
        object.__delattr__(self, name)
        if name == "apply":  # the class's apply is back (a test's monkeypatch undone): the table may run it again
            _resync(self)


class CableFriction(TableHook):
    """Capstan friction with stick/slip on the cables of one (model, data) pair.

    Created by :func:`install_cable_friction`; holds the per-hole states. ``active`` is
    False when μ = 0 (nothing was installed). ``anchor_ratio()`` is each cable's
    anchor-to-motor tension ratio at the last evaluation (1 without friction).
    """

    def __init__(
        self,
        model,
        data,
        config: CableFrictionConfig,
        tendon_ids: np.ndarray | None = None,
        kernel: CableKernel | None = None,
    ) -> None:
        import mujoco

        self.config = config
        # ``kernel``: the native cable path's (routing from the spatial twin; it evaluates the
        # pieces just before this hook in the same callback, so they are not computed twice).
        self.kernel = kernel if kernel is not None else CableKernel(model, tendon_ids)
        self._compute_pieces = kernel is None
        r = self.kernel.routing
        n_cables, n_pieces = len(r.cable_start), r.n_pieces
        self.z = np.zeros(n_pieces)  # stick/slip state of the hole before each piece
        self.s_prev = np.zeros(n_pieces)
        self.initialised = np.zeros(n_cables, dtype=np.bool_)
        self.piece_tension = np.zeros(n_pieces)
        self.wrap = np.zeros(n_pieces)  # β of the hole before each piece (rad)
        self.tension = np.zeros(n_cables)
        self.active = config.mu > 0.0
        self._fn: Any = kernels()["friction_forces"] if self.active else None
        # Tension sources MuJoCo puts along each tendon: its actuators and its own spring/damper.
        trn_tendon = int(mujoco.mjtTrn.mjTRN_TENDON)
        act_ids, act_owner = [], []
        for c, t in enumerate(r.tendon_ids):
            for a in np.flatnonzero((model.actuator_trntype == trn_tendon) & (model.actuator_trnid[:, 0] == t)):
                act_ids.append(int(a))
                act_owner.append(c)
        self._act_ids = np.array(act_ids, dtype=np.int64)
        self._act_owner = np.array(act_owner, dtype=np.int64)
        self._ten_k = np.array(model.tendon_stiffness[r.tendon_ids], dtype=float)
        self._ten_b = np.array(model.tendon_damping[r.tendon_ids], dtype=float)
        self._ten_spring = np.array(model.tendon_lengthspring[r.tendon_ids], dtype=float).reshape(-1, 2)
        # Views into data's buffers (fixed for its lifetime): no per-step attribute lookups.
        self._views = (data.qpos, data.actuator_force, data.ten_length, data.ten_velocity, data.qfrc_passive)
        self._model_ref = weakref.ref(model)
        self._data_ref = weakref.ref(data)
        self._key = data._address
        self._error: BaseException | None = None

    table_kind = "friction"

    def table_arrays(self) -> tuple[Any, ...]:
        """The kernel's array arguments, in order (``native_callback.FRICTION_ARRAYS``)."""
        r, k = self.kernel.routing, self.kernel
        qpos, actuator_force, ten_length, ten_velocity, qfrc_passive = self._views
        return (
            qpos, r.seg_ball, r.seg_njnt, r.seg_qadr, r.seg_qref, r.seg_axes, r.seg_bpos, r.seg_bmat, r.seg_jpos,
            r.seg_dofadr, r.piece_seg, r.piece_parent, r.piece_child, r.cable_start, r.cable_end, r.tendon_ids,
            self._act_ids, self._act_owner, actuator_force, self._ten_k, self._ten_b, self._ten_spring,
            ten_length, ten_velocity, self.z, self.s_prev, self.initialised,
            self.tension, k.seg_R, k.seg_w, k.length, k.direction, k.grad, self.piece_tension, self.wrap, qfrc_passive,
        )  # fmt: skip

    # -------------------------------------------------------------- tensions and forces
    def apply(self, model, data) -> None:
        """Add the friction correction to ``data.qfrc_passive`` (the callback's work).

        The passive stage runs before MuJoCo's actuation stage, so the actuator forces of
        the current state are computed first (``mj_fwdActuation``, ~1 µs; MuJoCo redoes it).
        """
        import mujoco

        if self._act_ids.size:
            mujoco.mj_fwdActuation(model, data)
        r, k, cfg = self.kernel.routing, self.kernel, self.config
        qpos, actuator_force, ten_length, ten_velocity, qfrc_passive = self._views
        self._fn(
            qpos, r.seg_ball, r.seg_njnt, r.seg_qadr, r.seg_qref, r.seg_axes, r.seg_bpos, r.seg_bmat, r.seg_jpos,
            r.seg_dofadr, r.piece_seg, r.piece_parent, r.piece_child, r.cable_start, r.cable_end, r.tendon_ids,
            self._act_ids, self._act_owner, actuator_force, self._ten_k, self._ten_b, self._ten_spring,
            ten_length, ten_velocity, cfg.mu, cfg.presliding, cfg.base_hole, self.z, self.s_prev, self.initialised,
            self.tension, k.seg_R, k.seg_w, k.length, k.direction, k.grad, self.piece_tension, self.wrap, qfrc_passive,
            self._compute_pieces,
        )  # fmt: skip

    def anchor_ratio(self) -> np.ndarray:
        """(C,) anchor / motor tension of each cable at the last evaluation (1: no loss)."""
        r = self.kernel.routing
        out = np.ones(len(r.cable_start))
        if not self.active:
            return out
        last = self.piece_tension[r.cable_end - 1]
        np.divide(last, self.tension, out=out, where=self.tension > 1e-9)  # (the same quotients, no masked copies)
        return out

    def wraps(self) -> np.ndarray:
        """(C,) total wrap angle (rad) of each cable over its holes at the last evaluation."""
        r = self.kernel.routing
        return np.array(
            [self.wrap[a:b].sum() for a, b in zip(r.cable_start, r.cable_end)]
        )

    def reset(self) -> None:
        """Forget the stick/slip history (the next evaluation starts from z = 0)."""
        self.z[:] = 0.0
        self.initialised[:] = False

    def uninstall(self) -> None:
        """Stop acting on this data (the global callback stays, acting on the others)."""
        data = self._data_ref()
        if data is not None:
            _unregister(data._address, self)

    def check(self) -> None:
        """Raise the first error the passive callback met (a C callback cannot raise itself)."""
        if self.error is not None and not isinstance(self.error, Exception):
            raise self.error  # an interrupt delivered inside the callback
        if self.error is not None:
            raise RuntimeError(
                f"cable friction failed in the passive callback: {self.error!r}"
            ) from self.error


# The process-global passive callback dispatches to the (model, data) pairs registered here
# and leaves every other model alone (sweeps and tests build several in one process); it
# calls whatever callback was installed before it first. It is a ctypes C callback taking
# the raw pointers: MuJoCo also runs the passive stage on internal mjData while compiling
# a model, which a plain Python callback cannot receive (the bindings raise there).
# Per data address, the hooks run in order (the native cable path first, then friction).
_REGISTRY: dict[int, list[Any]] = {}
_C_CALLBACK: list[Any] = []
# A signal handler (Ctrl-C, SIGTERM) may run inside the callback's Python code; ctypes would
# swallow its exception. The unraisable hook keeps it here and raise_pending() re-raises it
# from ordinary Python code (the run's observer calls it every tick).
_PENDING: list[BaseException] = []
_PREVIOUS_UNRAISABLE: list[Any] = []


def _unraisable_hook(unraisable: Any) -> None:
    if unraisable.object is _passive_callback and unraisable.exc_value is not None:
        _PENDING.append(unraisable.exc_value)
        return
    _PREVIOUS_UNRAISABLE[0](unraisable)


_UNREGISTERED_NATIVE = ("a model with native cables was stepped with an MjData not made by NativeCables.make_data"
                        " (its cables would have zero length)")


def raise_pending() -> None:
    """Re-raise an exception (e.g. a signal handler's) that interrupted the passive callback."""
    if _PENDING:
        exc = _PENDING[0]
        _PENDING.clear()
        raise exc
    nc = sys.modules.get(__package__ + ".native_callback")
    if nc is not None and nc.TABLE[nc.H_PENDING]:  # flagged by the compiled callback
        nc.TABLE[nc.H_PENDING] = 0
        raise RuntimeError(_UNREGISTERED_NATIVE)


def _passive_callback(model_ptr: int | None, data_ptr: int | None) -> None:
    hooks = _REGISTRY.get(data_ptr or 0)
    if hooks is None:
        if model_ptr in _native_models() and not _PENDING:
            _PENDING.append(RuntimeError(_UNREGISTERED_NATIVE))
        return
    for handle in hooks:
        model, data = handle._model_ref(), handle._data_ref()
        if model is None or data is None or model._address != model_ptr:
            return
        try:
            handle.apply(model, data)
        except BaseException as exc:  # noqa: BLE001 - a C callback cannot raise: kept for CableFriction.check()
            # Ctrl-C/SIGTERM land here too when the signal arrives inside the callback: kept and
            # re-raised after mj_step (ctypes would print it and drop it; the run then looked diverged).
            if handle.error is None:
                handle.error = exc
            return


def _native_models() -> dict[int, Any]:
    from .cable_path import _NATIVE_MODELS

    return _NATIVE_MODELS


def register_passive(data: Any, handle: Any, first: bool = False) -> None:
    """Run ``handle.apply(model, data)`` in the passive stage of every step of ``data``.

    ``first``: before the hooks already registered (the native cable path must write the
    cables' geometry before friction reads it). Dropped when ``data`` is freed.
    """
    key = data._address
    hooks = _REGISTRY.setdefault(key, [])
    if not hooks:
        weakref.finalize(data, _unregister, key, None)
    hooks.insert(0 if first else len(hooks), handle)
    _sync(key)
    _ensure_callback()


# The compiled callback (``native_callback``, a numba cfunc: no Python per step) runs the same
# kernels from a table of the registered datas' arrays; the Python callback above is the
# fallback (CONTINUUM_SIM_PY_CALLBACK=1, or whenever a registration does not fit the table).
COMPILED_CALLBACK = os.environ.get("CONTINUUM_SIM_PY_CALLBACK", "") in ("", "0")
_SLOTS: dict[int, int] = {}  # data address -> table row
_SLOT_HOOKS: dict[int, tuple[Any, Any]] = {}  # data address -> (native hook, friction hook) in that row
_UNFIT: set[int] = set()  # data addresses whose hooks only the Python callback can run


def _table() -> Any:
    from . import native_callback

    return native_callback


def _row_for(key: int, hooks: list[Any]) -> tuple[Any, Any, np.ndarray] | None:
    """(native hook, friction hook, table row) for the hooks of ``key``; None: they do not fit the table."""
    nc = _table()
    native = friction = None
    for handle in hooks:
        kind = getattr(handle, "table_kind", None)
        own = vars(handle).get("apply")  # replaced on the instance: only Python can call it
        if own is not None and not (getattr(own, "__func__", None) is type(handle).apply and own.__self__ is handle):
            return None  # (the class's own method set back on the instance, as undoing a monkeypatch does, is fine)
        if kind == "native" and native is None and friction is None:
            native = handle
        elif kind == "friction" and friction is None and handle.active:
            friction = handle
        else:
            return None
    models = {h._model_ref() for h in (native, friction) if h is not None}
    if len(models) != 1 or None in models:
        return None
    model = models.pop()
    row = np.zeros(nc.ROW, dtype=np.int64)
    row[nc.C_DATA] = key
    row[nc.C_MODEL] = model._address
    if native is not None:
        row[nc.C_NATIVE] = 1
        if not nc.fill_arrays(row, nc.C_ARRAYS, nc.NATIVE_ARRAYS, native.table_arrays()):
            return None
    if friction is not None:
        row[nc.C_FRICTION] = 1
        row[nc.C_FWDACT] = int(friction._act_ids.size > 0)
        row[nc.C_COMPUTE] = int(friction._compute_pieces)
        row[nc.C_BASE_HOLE] = int(friction.config.base_hole)
        floats = row.view(np.float64)
        floats[nc.C_MU] = friction.config.mu
        floats[nc.C_PRESLIDING] = friction.config.presliding
        if not nc.fill_arrays(row, nc.C_FARRAYS, nc.FRICTION_ARRAYS, friction.table_arrays()):
            return None
    return native, friction, row


def _harvest(key: int, slot: int) -> None:
    """Move the error flags of ``key``'s table row into its hooks' ``error``."""
    nc = _table()
    base = nc.slot_base(slot)
    if not (nc.TABLE[base + nc.C_ERR_NATIVE] or nc.TABLE[base + nc.C_ERR_FRICTION]):
        return  # (the per-tick case: nothing flagged, nothing to move)
    for handle, column in zip(_SLOT_HOOKS.get(key, (None, None)), (nc.C_ERR_NATIVE, nc.C_ERR_FRICTION)):
        if handle is not None and nc.TABLE[base + column] and handle._error is None:
            handle._error = RuntimeError("the compiled passive callback: the kernel raised (run with "
                                         "CONTINUUM_SIM_PY_CALLBACK=1 for the exception)")
        nc.TABLE[base + column] = 0


def _table_error(handle: Any) -> None:
    key = handle._key
    slot = _SLOTS.get(key)
    if slot is not None and handle in _SLOT_HOOKS.get(key, ()):
        _harvest(key, slot)


def _sync(key: int) -> None:
    """Rewrite the compiled callback's table row of the data at ``key`` from its registered hooks."""
    _UNFIT.discard(key)
    hooks = _REGISTRY.get(key)
    if not COMPILED_CALLBACK or (not hooks and key not in _SLOTS):
        return
    nc = _table()
    slot = _SLOTS.pop(key, None)
    if slot is not None:
        _harvest(key, slot)
        base = nc.slot_base(slot)
        nc.TABLE[base + nc.C_DATA] = 0  # first: the callback no longer matches this row
        nc.TABLE[base:base + nc.ROW] = 0
        _SLOT_HOOKS.pop(key, None)
    if hooks:
        fit = _row_for(key, hooks)
        free = sorted(set(range(nc.MAX_SLOTS)) - set(_SLOTS.values()))
        if fit is None or not free:
            _UNFIT.add(key)
        else:
            native, friction, row = fit
            slot = free[0]
            base = nc.slot_base(slot)
            nc.TABLE[base + 1:base + nc.ROW] = row[1:]
            nc.TABLE[nc.H_NSLOTS] = max(int(nc.TABLE[nc.H_NSLOTS]), slot + 1)
            nc.TABLE[base + nc.C_DATA] = key  # last: the row is complete before the callback can match it
            _SLOTS[key] = slot
            _SLOT_HOOKS[key] = (native, friction)
    nc.TABLE[nc.H_NSLOTS] = max(_SLOTS.values(), default=-1) + 1


def _resync(handle: Any) -> None:
    key = getattr(handle, "_key", None)
    if key is not None and handle in _REGISTRY.get(key, ()):
        _sync(key)
        _ensure_callback()


def sync_native_models() -> None:
    """Copy the native models' addresses into the compiled callback's table (its unregistered-data report)."""
    nc = sys.modules.get(__package__ + ".native_callback")
    if nc is None:
        return
    addresses = list(_native_models())[: nc.MAX_MODELS]
    nc.TABLE[nc.H_NMODELS] = 0
    nc.TABLE[nc.H_MODELS:nc.H_MODELS + len(addresses)] = addresses
    nc.TABLE[nc.H_NMODELS] = len(addresses)
    if _REGISTRY and _COMPILED and len(_native_models()) > nc.MAX_MODELS:
        _ensure_callback()  # too many to list: the Python callback reports them


def _wanted_callback() -> Any:
    """The compiled callback, unless the fallback is asked for or some registration needs Python."""
    if not COMPILED_CALLBACK or _UNFIT or _UNAVAILABLE:
        return _C_CALLBACK[0]
    nc = _table()
    if len(_native_models()) > nc.MAX_MODELS:
        return _C_CALLBACK[0]
    if not _COMPILED:
        from .jit import sigint_deferred

        try:
            with sigint_deferred():
                _COMPILED.append(nc.build())
        except OSError:  # MuJoCo's library not found by path: the Python callback (the same numbers)
            _UNAVAILABLE.append(True)
            return _C_CALLBACK[0]
        sync_native_models()
    return _COMPILED[0]


_UNAVAILABLE: list[bool] = []  # the compiled callback could not be built in this process


_COMPILED: list[Any] = []


def _ensure_callback() -> None:
    import ctypes

    import mujoco

    if not _C_CALLBACK:
        _C_CALLBACK.append(ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)(_passive_callback))
    if sys.unraisablehook is not _unraisable_hook:
        _PREVIOUS_UNRAISABLE[:] = [sys.unraisablehook]
        sys.unraisablehook = _unraisable_hook
    wanted = _wanted_callback()
    current = mujoco.get_mjcb_passive()
    if current is wanted:
        return
    if current is not None and current is not _C_CALLBACK[0] and not (_COMPILED and current is _COMPILED[0]):
        raise RuntimeError(
            "another MuJoCo passive callback is installed; cable friction cannot share it"
        )
    mujoco.set_mjcb_passive(wanted)


def _unregister(key: int, handle: Any) -> None:
    """Drop ``handle`` (None: every hook) of the data at ``key``; with none left, hand the global callback back."""
    hooks = _REGISTRY.get(key, [])
    if handle is None:
        hooks.clear()
    elif handle in hooks:
        hooks.remove(handle)
    if not hooks:
        _REGISTRY.pop(key, None)
    _sync(key)
    if _C_CALLBACK:
        import mujoco

        current = mujoco.get_mjcb_passive()
        ours = current is _C_CALLBACK[0] or (_COMPILED and current is _COMPILED[0])
        if not _REGISTRY and ours:
            mujoco.set_mjcb_passive(None)
        elif _REGISTRY and ours:
            _ensure_callback()  # the last registration needing Python may be gone


def _compile_outside_the_callback(model, data, config: CableFrictionConfig, tendon_ids: np.ndarray | None,
                                  kernel: CableKernel | None) -> None:
    """Run the kernels once on a scratch copy of ``data`` so numba compiles (or loads its cache) here.

    Compiling inside the ctypes passive callback takes seconds on a cold cache, and a Ctrl-C
    landing there was lost (a fresh clone's first interrupted run completed with exit 0).
    The scratch copy keeps the real data's stick/slip state untouched.
    """
    import mujoco

    with sigint_deferred():
        scratch = mujoco.MjData(model)
        mujoco.mj_copyData(scratch, model, data)
        CableFriction(model, scratch, config, tendon_ids, kernel).apply(model, scratch)


def install_cable_friction(
    model, data, config: CableFrictionConfig, tendon_ids: np.ndarray | None = None,
    kernel: CableKernel | None = None,
) -> CableFriction:
    """Attach cable friction to ``data`` of ``model``; returns its handle.

    With μ = 0 nothing is registered (the model runs exactly as before) and the handle
    reports anchor ratios of 1. The stick/slip state starts neutral (z = 0) at the first
    evaluation; it lives in the handle, keyed to this ``data`` (dropped when it is freed).
    ``kernel``: the native cable path's kernel of this ``data`` (``NativeCables.data_kernel``:
    it evaluates the pieces before friction in the same callback, friction reads them).
    """
    handle = CableFriction(model, data, config, tendon_ids, kernel)
    if handle.active:
        _compile_outside_the_callback(model, data, config, tendon_ids, kernel)
        register_passive(data, handle)
    return handle
