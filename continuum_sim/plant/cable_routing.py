"""Which holes each cable passes, read from a compiled model's spatial tendons: the static input of the cable kernels.

Each arm cable is built as ONE site-only spatial tendon through its hole on every disk
(``model.arm``). A *piece* joins two consecutive holes, on a parent disk and its child; its
length depends only on the joints of the *segment* (the child body) it spans (SPEC §2), so
its gradient has at most 3 entries. The kernels (``cable_kernels``) read MuJoCo's own
kinematics of the step (hole sites, hinge axes and anchors, body frames) through these
indices; the same routing serves a model with the spatial tendons and its native twin
(``cable_path``: the same bodies, joints and sites).
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from .cable_kernels import cable_pieces

CABLE_TENDON_PATTERN = r"(^|/)cable_\d+_\d+$"


@dataclass(frozen=True)
class CableRouting:
    """Static description of the cables of a compiled model, read from its tendons.

    Segment arrays (one entry per disk body a piece ends on): ``body``, ``ball`` flag, dof
    count ``njnt`` (3 for a ball), joint ids ``jnt`` (the ball's id three times), first dof
    address. Piece arrays: segment index, parent and child hole sites, the body of the
    cable's first hole (the arm base: piece directions are written in its frame). Cable c
    owns the pieces ``cable_start[c]:cable_end[c]``, base to anchor.
    """

    tendon_ids: np.ndarray
    names: tuple[str, ...]
    seg_body: np.ndarray
    seg_ball: np.ndarray
    seg_njnt: np.ndarray
    seg_jnt: np.ndarray
    seg_dofadr: np.ndarray
    piece_seg: np.ndarray
    piece_psite: np.ndarray
    piece_csite: np.ndarray
    piece_base: np.ndarray
    cable_start: np.ndarray
    cable_end: np.ndarray

    @property
    def n_pieces(self) -> int:
        return int(self.piece_seg.shape[0])

    @property
    def n_cables(self) -> int:
        return int(self.cable_start.shape[0])


def cable_tendons(model: Any, pattern: str = CABLE_TENDON_PATTERN) -> np.ndarray:
    """Ids of the spatial tendons whose names match ``pattern`` (the arm cables)."""
    import mujoco

    rx = re.compile(pattern)
    ids = [t for t in range(model.ntendon) if rx.search(model.tendon(t).name or "")]
    for t in ids:
        adr = model.tendon_adr[t]
        if any(model.wrap_type[adr + k] != mujoco.mjtWrap.mjWRAP_SITE for k in range(model.tendon_num[t])):
            raise ValueError(f"tendon {model.tendon(t).name!r} is not a site-only spatial tendon")
    return np.array(ids, dtype=np.int64)


def cable_routing(model: Any, tendon_ids: np.ndarray | None = None) -> CableRouting:
    """Read the cable routing (sites, disks, joints) of ``model`` (its spatial tendons) for the kernels.

    Each consecutive pair of a tendon's sites must sit on a parent disk and its child,
    joined by one ball joint or 1–3 hinges sharing one anchor (what the arm builder makes).
    """
    if tendon_ids is None:
        tendon_ids = cable_tendons(model)
    tendon_ids = np.asarray(tendon_ids, dtype=np.int64)
    seg_index: dict[int, int] = {}
    seg: dict[str, list[Any]] = {k: [] for k in ("body", "ball", "njnt", "jnt", "dofadr")}
    piece: dict[str, list[int]] = {k: [] for k in ("seg", "psite", "csite", "base")}
    start: list[int] = []
    end: list[int] = []
    for t in tendon_ids:
        name = model.tendon(int(t)).name
        adr, num = int(model.tendon_adr[t]), int(model.tendon_num[t])
        sites = [int(model.wrap_objid[adr + k]) for k in range(num)]
        start.append(len(piece["seg"]))
        for parent_site, child_site in itertools.pairwise(sites):
            body = int(model.site_bodyid[child_site])
            if int(model.body_parentid[body]) != int(model.site_bodyid[parent_site]):
                raise ValueError(f"tendon {name!r}: sites {parent_site} and {child_site} are not on a parent and its child")
            if body not in seg_index:
                seg_index[body] = len(seg["body"])
                _add_segment(model, body, seg, name)
            piece["seg"].append(seg_index[body])
            piece["psite"].append(parent_site)
            piece["csite"].append(child_site)
            piece["base"].append(int(model.site_bodyid[sites[0]]))
        end.append(len(piece["seg"]))
        if end[-1] == start[-1]:
            raise ValueError(f"tendon {name!r} has fewer than two sites")
    return CableRouting(
        tendon_ids=tendon_ids,
        names=tuple(model.tendon(int(t)).name for t in tendon_ids),
        seg_body=np.array(seg["body"], dtype=np.int64),
        seg_ball=np.array(seg["ball"], dtype=np.bool_),
        seg_njnt=np.array(seg["njnt"], dtype=np.int64),
        seg_jnt=np.array(seg["jnt"], dtype=np.int64).reshape(-1, 3),
        seg_dofadr=np.array(seg["dofadr"], dtype=np.int64),
        piece_seg=np.array(piece["seg"], dtype=np.int64),
        piece_psite=np.array(piece["psite"], dtype=np.int64),
        piece_csite=np.array(piece["csite"], dtype=np.int64),
        piece_base=np.array(piece["base"], dtype=np.int64),
        cable_start=np.array(start, dtype=np.int64),
        cable_end=np.array(end, dtype=np.int64),
    )


def _add_segment(model: Any, body: int, seg: dict[str, list[Any]], tendon: str) -> None:
    import mujoco

    first, count = int(model.body_jntadr[body]), int(model.body_jntnum[body])
    types = [int(model.jnt_type[first + k]) for k in range(count)]
    ball = types == [int(mujoco.mjtJoint.mjJNT_BALL)]
    if not ball and not (1 <= count <= 3 and all(t == int(mujoco.mjtJoint.mjJNT_HINGE) for t in types)):
        raise ValueError(f"tendon {tendon!r}: body {model.body(body).name!r} needs one ball joint or 1-3 hinges")
    if any(not np.allclose(model.jnt_pos[first + k], model.jnt_pos[first]) for k in range(count)):
        raise ValueError(f"body {model.body(body).name!r}: its hinges must share one anchor")
    jnt = np.zeros(3, dtype=np.int64)
    jnt[:] = first
    if not ball:
        jnt[:count] = np.arange(first, first + count)
    seg["body"].append(body)
    seg["ball"].append(ball)
    seg["njnt"].append(3 if ball else count)
    seg["jnt"].append(jnt)
    seg["dofadr"].append(int(model.jnt_dofadr[first]))


class CablePieces:
    """Per-piece scratch of one MjData: ``length`` (P,), ``direction`` (P, 3, arm-base frame),
    ``grad`` (P, 3): ∂l_i/∂(local dof k) for the ≤ 3 dofs of the segment piece i spans (dof
    address ``routing.seg_dofadr[routing.piece_seg[i]] + k``).

    Written by the passive kernels each step; :meth:`evaluate` fills it from a data whose
    kinematics ran (``mj_kinematics``), for inspection and tests. Each MjData has its own:
    the kernels run without the GIL, two datas of one model may step in two threads.
    """

    def __init__(self, routing: CableRouting) -> None:
        self.routing = routing
        self.length = np.zeros(routing.n_pieces)
        self.direction = np.zeros((routing.n_pieces, 3))
        self.grad = np.zeros((routing.n_pieces, 3))

    def evaluate(self, data: Any) -> None:
        """Fill the pieces from ``data``'s kinematics (the kernel the passive callback runs)."""
        r = self.routing
        cable_pieces(data.site_xpos, data.xmat, data.xaxis, data.xanchor, r.piece_psite, r.piece_csite, r.piece_seg,
                     r.piece_base, r.seg_jnt, r.seg_njnt, r.seg_ball, r.seg_body, self.length, self.direction, self.grad)

    def cable_lengths(self) -> np.ndarray:
        """(C,) total length of each cable at the last evaluation."""
        r = self.routing
        return np.array([self.length[a:b].sum() for a, b in zip(r.cable_start, r.cable_end, strict=True)])

    def cable_jacobian(self, nv: int) -> np.ndarray:
        """(C, nv) dense ∂L_c/∂qvel at the last evaluation (what MuJoCo's ten_J holds)."""
        r = self.routing
        J = np.zeros((r.n_cables, nv))
        for c, (a, b) in enumerate(zip(r.cable_start, r.cable_end, strict=True)):
            for i in range(a, b):
                g = r.piece_seg[i]
                for k in range(int(r.seg_njnt[g])):
                    J[c, r.seg_dofadr[g] + k] += self.grad[i, k]
        return J
