"""The native cable path: each cable a fixed tendon whose exact length and Jacobian come from a kernel.

Why: in the generated model every cable is a spatial tendon through a site on each disk it
passes (18 cables, 360 pieces). MuJoCo builds each tendon's Jacobian piece by piece
through the whole kinematic chain, ~80 µs of a ~240 µs step of the dual-arm scene
(`python benchmarks/scenario.py` reports the split). Yet a piece's length depends only on
the joints of the one segment it spans (SPEC §2), so the same length and gradient cost a
few µs from MuJoCo's own kinematics of the step.

How: the compiled run model replaces every arm cable's ``<spatial>`` tendon by a
``<fixed>`` tendon over the joints the cable spans, all coefficients 0 (so MuJoCo's own
tendon length, Jacobian and passive force are exactly 0 and the sparsity of ``ten_J`` and
of the actuator moments is the spatial one). The passive-force callback (``passive``) then
runs ``cable_kernels.native_cables`` before the actuation stage: from the hole sites'
positions, each hinge's axis and anchor (no trigonometry), piece by piece (length
|x_c − x_p| in MuJoCo's arithmetic for a site-to-site segment; gradient u·(a × (x_c − anchor))
over the ≤ 3 hinges of the segment the piece spans) it writes

* ``ten_length``, ``ten_J`` (the scatter of the pieces' local gradients), ``ten_velocity``;
* each cable actuator's ``actuator_length``/``actuator_moment``/``actuator_velocity``
  (gear × the tendon's), which MuJoCo had copied from the zero tendon;
* the tendon's spring (dead band between its two spring lengths) and damper, added to
  ``qfrc_spring``/``qfrc_damper``/``qfrc_passive`` through the exact Jacobian.

The actuation stage, the constraint solver and implicitfast's velocity derivatives (the
tendon damping and the actuators' bias terms, read from ``ten_J``/``actuator_moment`` at
integration time) then see what the spatial tendon gives: MuJoCo's own spatial tendons
are the test oracle (``tests/test_cable_path.py``, 1e-12 relative). The spatial model is
kept for rendering (the video draws the cables) and is what ``models/`` holds.

The callback acts only on the MjData made by :meth:`NativeCables.make_data`: a data of a
native model without its runtime would see cables of zero length, so stepping one is
flagged and reported (``passive.raise_pending``, called by the tick loop).
``ModelOptions.cable_path = "spatial"`` runs MuJoCo's own spatial tendons (the plain path,
for comparison).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Any

import numpy as np

from . import passive
from .cable_routing import cable_routing, cable_tendons

# <fixed> accepts these of a <spatial> tendon's attributes; the visual ones (width, rgba,
# material) and wrapping have no meaning for a fixed tendon.
_FIXED_ATTRIBUTES = frozenset({
    "name", "class", "group", "limited", "range", "solreflimit", "solimplimit", "solreffriction", "solimpfriction",
    "frictionloss", "springlength", "stiffness", "damping", "margin", "user", "armature", "actuatorfrclimited",
    "actuatorfrcrange",
})


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
    """The native cable path of one compiled model: its spatial twin, the routing and the kernel's maps.

    ``model`` is the model to simulate (fixed tendons), ``spatial_model`` the same scene with
    MuJoCo's spatial tendons (render it; its state layout is the same). Create every MjData
    you step with :meth:`make_data`.
    """

    def __init__(self, spatial_model: Any, model: Any, tendon_ids: np.ndarray) -> None:
        import weakref

        self.spatial_model = spatial_model
        self._model_ref = weakref.ref(model)  # the process's dispatch lists this object: it must not keep the model
        self.routing = r = cable_routing(spatial_model, tendon_ids)  # from the sites (same ids in both models)
        if r.seg_ball.any():
            raise ValueError("native cables need hinge joints (a fixed tendon cannot span a ball joint); "
                             "with joint = ball a run uses model.cable_path = spatial")
        self.piece_jadr = np.zeros((r.n_pieces, 3), dtype=np.int64)
        for c, t in enumerate(r.tendon_ids):
            adr, nnz = int(model.ten_J_rowadr[t]), int(model.ten_J_rownnz[t])
            column = {int(dof): adr + j for j, dof in enumerate(model.ten_J_colind[adr:adr + nnz])}
            for i in range(r.cable_start[c], r.cable_end[c]):
                g = r.piece_seg[i]
                for k in range(int(r.seg_njnt[g])):
                    dof = int(r.seg_dofadr[g] + k)
                    if dof not in column:
                        raise ValueError(f"native cables: tendon {r.names[c]!r} has no Jacobian entry for dof {dof}")
                    self.piece_jadr[i, k] = column[dof]
        self.maps = {"piece_jadr": self.piece_jadr,
                     "ten_rowadr": np.array(model.ten_J_rowadr, dtype=np.int64),
                     "ten_rownnz": np.array(model.ten_J_rownnz, dtype=np.int64),
                     "ten_colind": np.array(model.ten_J_colind, dtype=np.int64)}
        passive.track_native_model(model, self)

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

        model = self.model
        data = mujoco.MjData(model)
        runtime = passive.attach(model, data, self.routing)
        runtime.bind(**self.maps)
        runtime.set(err_native=0, native=1)
        return data


def native_cables(model: Any) -> NativeCables | None:
    """The native cable path of ``model`` (None: MuJoCo's own tendons, nothing to register)."""
    owner = passive.native_owner(model)
    return owner if isinstance(owner, NativeCables) and owner._model_ref() is model else None


def release_data(data: Any) -> None:
    """Stop evaluating ``data``'s cables (its hooks leave the passive callback); for the end of a run."""
    passive.release(data)


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
    ids = cable_tendons(spatial)
    native = mujoco.MjModel.from_xml_string(native_cable_xml(xml, spatial, ids), assets)
    shorten_zero_tendons(native, ids)
    NativeCables(spatial, native, ids)  # listed under the native model's address (passive.native_owner)
    return native, spatial
