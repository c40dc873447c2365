"""The native cable path: each cable a fixed tendon whose exact length and Jacobian come from a kernel.

Why: in the generated model every cable is a spatial tendon through a site on each disk it
passes (18 cables, 360 pieces). MuJoCo builds each tendon's Jacobian piece by piece
through the whole kinematic chain, ~80 µs of a ~240 µs step of the dual-arm scene
(`python benchmarks/scenario.py` reports the split). Yet a piece's length depends only on
the joints of the one segment it spans (``friction.cable_pieces``, SPEC §2), so the same
length and gradient cost a few µs from the local joint angles.

How: the compiled run model replaces every arm cable's ``<spatial>`` tendon by a
``<fixed>`` tendon over the joints the cable spans, all coefficients 0 (so MuJoCo's own
tendon length, Jacobian and passive force are exactly 0 and the sparsity of ``ten_J`` and
of the actuator moments is the spatial one). MuJoCo's passive-force callback (shared with
cable friction: the numba cfunc of ``native_callback``, or ``friction._passive_callback``
with CONTINUUM_SIM_PY_CALLBACK=1) then writes, before the actuation stage,
from MuJoCo's own kinematics of the step (the hole sites' positions, each hinge's axis and
anchor: no trigonometry), piece by piece (length |x_c − x_p| in MuJoCo's arithmetic for a
site-to-site segment, so the lengths are the spatial tendon's bit for bit; gradient
u·(a × (x_c − anchor)) over the ≤ 3 hinges of the segment the piece spans):

* ``ten_length``, ``ten_J`` (the scatter of the pieces' local gradients), ``ten_velocity``;
* each cable actuator's ``actuator_length``/``actuator_moment``/``actuator_velocity``
  (gear × the tendon's), which MuJoCo had copied from the zero tendon;
* the tendon's spring (dead band between its two spring lengths) and damper, added to
  ``qfrc_spring``/``qfrc_damper``/``qfrc_passive`` through the exact Jacobian.

The actuation stage, the constraint solver and implicitfast's velocity derivatives (the
tendon damping and the actuators' bias terms, read from ``ten_J``/``actuator_moment`` at
integration time) then see exactly what the spatial tendon gives: forces agree to
~1e-13 relative (``tests/test_cable_path.py``). The spatial model is kept for rendering
(the video draws the cables) and is what ``models/`` holds.

The callback only acts on the MjData registered here (``NativeCables.make_data``): a data
of a native model that is not registered would see cables of zero length, so stepping
one is refused by :meth:`NativeCables.check` and reported by the tick loop.
``ModelOptions.cable_path = "spatial"`` runs MuJoCo's own spatial tendons (the plain path,
for comparison).
"""

from __future__ import annotations

import weakref
import xml.etree.ElementTree as ET
from typing import Any

import numpy as np

from . import friction as fr
from .jit import jit_in_place, sigint_deferred

# <fixed> accepts these of a <spatial> tendon's attributes; the visual ones (width, rgba,
# material) and wrapping have no meaning for a fixed tendon.
_FIXED_ATTRIBUTES = frozenset({
    "name", "class", "group", "limited", "range", "solreflimit", "solimplimit", "solreffriction", "solimpfriction",
    "frictionloss", "springlength", "stiffness", "damping", "margin", "user", "armature", "actuatorfrclimited",
    "actuatorfrcrange",
})


def _native_pieces(site_xpos, xaxis, xanchor, xmat, piece_psite, piece_csite, piece_seg, seg_jnt, seg_njnt,
                   piece_base, length, direction, grad):  # fmt: skip
    """Per piece from MuJoCo's own kinematics (position stage): length |x_c − x_p| (MuJoCo's
    arithmetic for a site-to-site tendon segment), the unit direction in the arm's base frame
    (what cable friction's wrap angles need) and ∂l/∂q_k = u·(a_k × (x_c − anchor_k)) for the
    hinges k of the segment the piece spans."""
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
        for k in range(3):
            if k < seg_njnt[g]:
                j = seg_jnt[g, k]
                r0 = site_xpos[c, 0] - xanchor[j, 0]
                r1 = site_xpos[c, 1] - xanchor[j, 1]
                r2 = site_xpos[c, 2] - xanchor[j, 2]
                a0, a1, a2 = xaxis[j, 0], xaxis[j, 1], xaxis[j, 2]
                grad[i, k] = u0 * (a1 * r2 - a2 * r1) + u1 * (a2 * r0 - a0 * r2) + u2 * (a0 * r1 - a1 * r0)
            else:
                grad[i, k] = 0.0


def _native_cables(
    qvel, site_xpos, xaxis, xanchor, xmat, piece_psite, piece_csite, seg_jnt, seg_njnt, seg_ball, piece_base,
    piece_seg, cable_start, cable_end, tendon_ids, piece_jadr,
    ten_rowadr, ten_rownnz, ten_colind, ten_stiffness, ten_damping, ten_spring,
    act_ids, act_owner, act_gear, moment_rowadr,
    length, direction, grad,
    ten_length, ten_J, ten_velocity, actuator_length, actuator_velocity, actuator_moment,
    qfrc_spring, qfrc_damper, qfrc_passive,
):  # fmt: skip
    """Exact cable lengths, Jacobians, velocities, actuator transmissions and tendon passive forces."""
    _native_pieces(site_xpos, xaxis, xanchor, xmat, piece_psite, piece_csite, piece_seg, seg_jnt, seg_njnt,
                   piece_base, length, direction, grad)
    for c in range(cable_start.shape[0]):
        t = tendon_ids[c]
        adr, nnz = ten_rowadr[t], ten_rownnz[t]
        for j in range(nnz):
            ten_J[adr + j] = 0.0
        L = 0.0
        for i in range(cable_start[c], cable_end[c]):
            L += length[i]
            g = piece_seg[i]
            ndof = 3 if seg_ball[g] else seg_njnt[g]
            for k in range(ndof):
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
    for a in range(act_ids.shape[0]):
        c = act_owner[a]
        t = tendon_ids[c]
        adr, nnz = ten_rowadr[t], ten_rownnz[t]
        gear = act_gear[a]
        act = act_ids[a]
        actuator_length[act] = gear * ten_length[t]
        actuator_velocity[act] = gear * ten_velocity[t]
        madr = moment_rowadr[act]
        for j in range(nnz):
            actuator_moment[madr + j] = gear * ten_J[adr + j]


_KERNELS: dict[str, Any] = {}


def kernels() -> dict[str, Any]:
    """The compiled kernel (numba; compiled or loaded from its disk cache on first use)."""
    if not _KERNELS:
        jit_in_place(globals(), ("_native_pieces", "_native_cables"))
        _KERNELS["native_cables"] = _native_cables
    return _KERNELS


# ------------------------------------------------------------------- model conversion
def native_cable_xml(xml: str, spatial_model: Any, tendon_ids: np.ndarray) -> str:
    """``xml`` (the spatial model's MJCF) with the tendons ``tendon_ids`` as zero-coefficient fixed tendons.

    Each fixed tendon lists the joints of every disk its spatial tendon's sites sit on past
    the first, so its ``ten_J`` row has the spatial tendon's sparsity; it stays in the
    spatial one's place (tendon ids unchanged).
    """
    m = spatial_model
    joints: dict[str, list[str]] = {}
    for t in tendon_ids:
        adr, num = int(m.tendon_adr[t]), int(m.tendon_num[t])
        bodies = [int(m.site_bodyid[m.wrap_objid[adr + k]]) for k in range(1, num)]
        joints[m.tendon(int(t)).name] = [
            m.joint(j).name for b in bodies for j in range(int(m.body_jntadr[b]), int(m.body_jntadr[b] + m.body_jntnum[b]))
        ]
    root = ET.fromstring(xml)
    replaced = 0
    for section in root.iter("tendon"):
        for index, element in enumerate(list(section)):
            name = element.get("name")
            if element.tag != "spatial" or name not in joints:
                continue
            fixed = ET.Element("fixed", {k: v for k, v in element.attrib.items() if k in _FIXED_ATTRIBUTES})
            for joint in joints[name]:
                ET.SubElement(fixed, "joint", {"joint": joint, "coef": "0"})
            section.remove(element)
            section.insert(index, fixed)
            replaced += 1
    if replaced != len(joints):
        raise ValueError(f"native cables: {len(joints) - replaced} of {len(joints)} cable tendons not found in the MJCF")
    return ET.tostring(root, encoding="unicode")


class NativeCables:
    """The native cable path of one compiled model: its spatial twin, routing and the kernel's maps.

    ``model`` is the model to simulate (fixed tendons), ``spatial_model`` the same scene with
    MuJoCo's spatial tendons (render it; its state layout is the same). Create every MjData
    you step with :meth:`make_data`.
    """

    def __init__(self, spatial_model: Any, model: Any, tendon_ids: np.ndarray) -> None:
        import mujoco

        self.spatial_model = spatial_model
        self._model_ref = weakref.ref(model)  # the registry below must not keep the model alive
        self.kernel = fr.CableKernel(spatial_model, tendon_ids)  # routing from the sites (same ids in both)
        r = self.kernel.routing
        if r.seg_ball.any():
            raise ValueError("native cables need hinge joints (a fixed tendon cannot span a ball joint); "
                             "with joint = ball a run uses model.cable_path = spatial")
        self.piece_jadr = np.zeros((r.n_pieces, 3), dtype=np.int64)
        for c, t in enumerate(r.tendon_ids):
            adr, nnz = int(model.ten_J_rowadr[t]), int(model.ten_J_rownnz[t])
            column = {int(dof): adr + j for j, dof in enumerate(model.ten_J_colind[adr:adr + nnz])}
            for i in range(r.cable_start[c], r.cable_end[c]):
                g = r.piece_seg[i]
                for k in range(3 if r.seg_ball[g] else r.seg_njnt[g]):
                    dof = int(r.seg_dofadr[g] + k)
                    if dof not in column:
                        raise ValueError(f"native cables: tendon {r.names[c]!r} has no Jacobian entry for dof {dof}")
                    self.piece_jadr[i, k] = column[dof]
        # The sites each piece joins, the hinges of each segment, the arm base each cable leaves.
        psite, csite, base = [], [], []
        for t in r.tendon_ids:
            adr, num = int(spatial_model.tendon_adr[t]), int(spatial_model.tendon_num[t])
            sites = [int(spatial_model.wrap_objid[adr + k]) for k in range(num)]
            psite += sites[:-1]
            csite += sites[1:]
            base += [int(spatial_model.site_bodyid[sites[0]])] * (num - 1)
        self.piece_psite = np.array(psite, dtype=np.int64)
        self.piece_csite = np.array(csite, dtype=np.int64)
        self.piece_base = np.array(base, dtype=np.int64)
        self.seg_jnt = np.zeros((len(r.seg_body), 3), dtype=np.int64)
        for g, body in enumerate(r.seg_body):
            for k in range(int(r.seg_njnt[g])):
                self.seg_jnt[g, k] = int(spatial_model.body_jntadr[body]) + k
        # Directions are written in the arm's base frame: friction's wrap angles then need no
        # segment rotations (its seg_R stays the identity; the routing's frames are not used).
        self.kernel.seg_R[:] = np.eye(3)
        trn_tendon = int(mujoco.mjtTrn.mjTRN_TENDON)
        owner = {int(t): c for c, t in enumerate(r.tendon_ids)}
        acts = [a for a in range(model.nu) if model.actuator_trntype[a] == trn_tendon and int(model.actuator_trnid[a, 0]) in owner]
        self.act_ids = np.array(acts, dtype=np.int64)
        self.act_owner = np.array([owner[int(model.actuator_trnid[a, 0])] for a in acts], dtype=np.int64)
        self.act_gear = np.array([model.actuator_gear[a, 0] for a in acts], dtype=float)
        self.ten_stiffness = np.array(model.tendon_stiffness[r.tendon_ids], dtype=float)
        self.ten_damping = np.array(model.tendon_damping[r.tendon_ids], dtype=float)
        self.ten_spring = np.array(model.tendon_lengthspring[r.tendon_ids], dtype=float).reshape(-1, 2)
        self.ten_rowadr = np.array(model.ten_J_rowadr, dtype=np.int64)
        self.ten_rownnz = np.array(model.ten_J_rownnz, dtype=np.int64)
        self.ten_colind = np.array(model.ten_J_colind, dtype=np.int64)
        self._fn = kernels()["native_cables"]
        _NATIVE_MODELS[model._address] = self
        weakref.finalize(model, _drop_model, model._address)
        fr.sync_native_models()

    def data_kernel(self, data: Any) -> Any:
        """The kernel (routing and scratch) of ``data``'s native cable hook: where the pieces of
        the step are (cable friction reads them). ``data`` must come from :meth:`make_data`."""
        for hook in fr._REGISTRY.get(data._address, ()):
            if isinstance(hook, _NativeData) and hook.cables is self and hook._data_ref() is data:
                return hook.kernel
        raise ValueError("native cables: this MjData was not made by NativeCables.make_data")

    @property
    def model(self) -> Any:
        """The model to simulate (fixed tendons); it must still exist."""
        model = self._model_ref()
        if model is None:
            raise RuntimeError("native cables: the model was freed")
        return model

    def make_data(self) -> Any:
        """A new MjData of ``model`` whose cables the passive callback evaluates (from its first mj_forward)."""
        import mujoco

        data = mujoco.MjData(self.model)
        handle = _NativeData(self, data)
        with sigint_deferred():  # compile (or load) the kernel here, not inside the C callback
            mujoco.mj_kinematics(self.model, data)
            handle.apply(self.model, data)
        fr.register_passive(data, handle, first=True)
        return data


class _NativeData(fr.TableHook):
    """The per-data hook: views into one MjData's buffers, its own kernel scratch, the shared maps."""

    def __init__(self, cables: NativeCables, data: Any) -> None:
        self.cables = cables
        self.kernel = cables.kernel.for_data()  # scratch of its own: the kernel runs without the GIL
        self._model_ref = cables._model_ref
        self._data_ref = weakref.ref(data)
        self._key = data._address
        self._error: BaseException | None = None
        self._views = (data.qvel, data.site_xpos, data.xaxis, data.xanchor, data.xmat, data.ten_length, data.ten_J,
                       data.ten_velocity, data.actuator_length, data.actuator_velocity, data.actuator_moment,
                       data.moment_rowadr, data.qfrc_spring, data.qfrc_damper, data.qfrc_passive)

    table_kind = "native"

    def table_arrays(self) -> tuple[Any, ...]:
        """The kernel's array arguments, in order (``native_callback.NATIVE_ARRAYS``)."""
        n, k = self.cables, self.kernel
        r = k.routing
        (qvel, site_xpos, xaxis, xanchor, xmat, ten_length, ten_J, ten_velocity, actuator_length, actuator_velocity,
         actuator_moment, moment_rowadr, qfrc_spring, qfrc_damper, qfrc_passive) = self._views
        return (
            qvel, site_xpos, xaxis, xanchor, xmat, n.piece_psite, n.piece_csite, n.seg_jnt, r.seg_njnt, r.seg_ball,
            n.piece_base, r.piece_seg, r.cable_start, r.cable_end, r.tendon_ids, n.piece_jadr,
            n.ten_rowadr, n.ten_rownnz, n.ten_colind, n.ten_stiffness, n.ten_damping, n.ten_spring,
            n.act_ids, n.act_owner, n.act_gear, moment_rowadr,
            k.length, k.direction, k.grad,
            ten_length, ten_J, ten_velocity, actuator_length, actuator_velocity, actuator_moment,
            qfrc_spring, qfrc_damper, qfrc_passive,
        )  # fmt: skip

    def apply(self, model: Any, data: Any) -> None:  # noqa: ARG002 - the passive hook's signature
        self.cables._fn(*self.table_arrays())


# Models with native cables (address -> NativeCables, dropped when the model is freed): the
# passive callback reports a data of one of these that was not made by make_data.
_NATIVE_MODELS: dict[int, NativeCables] = {}


def _drop_model(address: int) -> None:
    _NATIVE_MODELS.pop(address, None)
    fr.sync_native_models()


def native_cables(model: Any) -> NativeCables | None:
    """The native cable path of ``model`` (None: MuJoCo's own tendons, nothing to register)."""
    entry = _NATIVE_MODELS.get(model._address)
    if entry is None or entry._model_ref() is not model:
        return None
    return entry


def release_data(data: Any) -> None:
    """Stop evaluating ``data``'s cables (its hooks leave the passive callback); for the end of a run."""
    fr._unregister(data._address, None)


def make_data(model: Any) -> Any:
    """An MjData for ``model``: registered with its native cable path when it has one."""
    import mujoco

    cables = native_cables(model)
    return mujoco.MjData(model) if cables is None else cables.make_data()


def shorten_zero_tendons(model: Any, tendon_ids: np.ndarray) -> None:
    """Let MuJoCo's ``mj_tendon`` visit only the first joint of each zero-coefficient cable tendon.

    Why: ``mj_tendon`` merges every listed joint into the tendon's sparse Jacobian row with
    a full scan of the row (``mju_combineSparseInc``), so a fixed tendon over n joints costs
    O(n²): 41 of the 136+41 µs of a dual-arm ``mj_step`` (idle machine, ``timeit``), for a
    length and a Jacobian that are exactly 0 (every coefficient is 0) and that the kernel
    overwrites. The Jacobian's sparsity (``ten_J_rownnz``/``colind``, sized at compile time
    from the full joint list) is kept; only ``tendon_num`` drops to 1, so MuJoCo still
    writes the same exact zeros. Nothing in MuJoCo re-derives sizes from ``tendon_num`` after
    compiling (``mj_setConst`` would rebuild the sparsity from it: never call it on this model).
    """
    import mujoco

    for t in np.asarray(tendon_ids, dtype=np.int64):
        adr = int(model.tendon_adr[t])
        if model.wrap_type[adr] != mujoco.mjtWrap.mjWRAP_JOINT or np.any(model.wrap_prm[adr:adr + model.tendon_num[t]]):
            raise ValueError(f"tendon {model.tendon(int(t)).name!r} is not a zero-coefficient fixed tendon")
    model.tendon_num[tendon_ids] = 1


def compile_native(root: Any) -> tuple[Any, Any]:
    """(model with native cables, its spatial twin) compiled from the PyMJCF ``root`` of a scene.

    The twin is the scene exactly as built (what ``models/`` holds, what the video draws);
    the first is the one to simulate, with MjData from :func:`make_data`.
    """
    import mujoco

    xml, assets = root.to_xml_string(), root.get_assets()
    spatial = mujoco.MjModel.from_xml_string(xml, assets)
    ids = fr.cable_tendons(spatial)
    native = mujoco.MjModel.from_xml_string(native_cable_xml(xml, spatial, ids), assets)
    shorten_zero_tendons(native, ids)
    NativeCables(spatial, native, ids)  # registered under the native model's address
    return native, spatial
