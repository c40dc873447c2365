"""The scene contract: every id of the compiled scene the runtime reads or drives.

``SceneHandles.from_model`` resolves them once, from the builders' own names
(``model.names``, ``scene``, ``tools``) and the layout's arm<->tool pairing, so the runner,
controllers, observers and metrics index MuJoCo arrays with integers and never spell a
model name. A missing element is a ``KeyError`` naming it (the builders and this contract
disagree).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import mujoco
import numpy as np
from numpy.typing import NDArray

from ..geometry import ArmGeometry
from ..layout import ARMS, TaskLayout
from . import names
from .scene import PLATE_BODY, SAMPLE_BODY, SAMPLE_WELD
from .tools import CUTTER_GEOM, GRINDER, GRIPPER, GRIPPER_CABLE, SPINDLE_JOINT

IntArray = NDArray[np.int64]


class GeomKind(IntEnum):
    """What a geom belongs to, for sorting contacts (``SceneHandles.geom_kind``)."""

    OTHER = 0  # world: plate, sample, bench, pack, clamp, floor
    CUTTER = 1  # the grinder's cutting cylinder
    GRIPPER = 2  # any geom of the gripper tool
    FIRST_ARM = 3  # an arm (or its grinder housing) of ARMS[0]
    SECOND_ARM = 4  # … of ARMS[1]

    @classmethod
    def of_arm(cls, arm: str) -> GeomKind:
        return cls(cls.FIRST_ARM + ARMS.index(arm))


def name2id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    """MuJoCo id of ``name``; KeyError naming the element when the model has none."""
    index = mujoco.mj_name2id(model, kind, name)
    if index < 0:
        raise KeyError(f"the scene has no {kind.name.removeprefix('mjOBJ_').lower()} named {name!r}")
    return int(index)


@dataclass(frozen=True)
class SceneHandles:
    """Ids into one compiled scene (valid for that ``MjModel`` only)."""

    arms: tuple[str, ...]
    tool_arm: dict[str, str]  # tool -> arm that carries it (from the layout)
    tcp_site: dict[str, int]
    cable_actuators: dict[str, IntArray]  # per arm, cables in model order (3 per section, base to tip)
    cable_tendons: dict[str, IntArray]
    disk_bodies: dict[str, IntArray]  # disks 1..N (the base plate excluded)
    disk_radii: dict[str, NDArray[np.float64]]
    spindle_actuator: int
    spindle_dof: int
    cutter_geom: int
    gripper_actuator: int  # the gripper's closing cable
    plate_body: int
    sample_body: int
    sample_weld: int  # equality; inactive once the sample is cut free
    geom_kind: NDArray[np.int64]  # GeomKind per geom

    @property
    def grinder_arm(self) -> str:
        return self.tool_arm[GRINDER]

    @property
    def gripper_arm(self) -> str:
        return self.tool_arm[GRIPPER]

    @classmethod
    def from_model(cls, model: mujoco.MjModel, geometry: ArmGeometry, layout: TaskLayout) -> SceneHandles:
        """Resolve every handle; ``geometry`` is the model's geometry (``options.model_geometry``)."""
        obj = mujoco.mjtObj
        n_disks = sum(s.n_segments for s in geometry.sections)
        radii = np.concatenate([[s.disk_diameter / 2] * s.n_segments for s in geometry.sections])
        tool_arm = {layout.tool_of(arm): arm for arm in ARMS}
        grinder, gripper = tool_arm[GRINDER], tool_arm[GRIPPER]
        act, ten, disks, tcp = {}, {}, {}, {}
        for arm in ARMS:
            cables = names.arm_cable_names(arm, geometry.n_sections)
            act[arm] = np.array([name2id(model, obj.mjOBJ_ACTUATOR, n) for n in cables])
            ten[arm] = np.array([name2id(model, obj.mjOBJ_TENDON, n) for n in cables])
            disks[arm] = np.array(
                [name2id(model, obj.mjOBJ_BODY, names.scoped(arm, names.disk(i))) for i in range(1, n_disks + 1)]
            )
            tcp[arm] = name2id(model, obj.mjOBJ_SITE, names.scoped(arm, names.TCP_SITE))
        spindle_joint = name2id(model, obj.mjOBJ_JOINT, names.scoped(grinder, GRINDER, SPINDLE_JOINT))
        return cls(
            arms=ARMS,
            tool_arm=tool_arm,
            tcp_site=tcp,
            cable_actuators=act,
            cable_tendons=ten,
            disk_bodies=disks,
            disk_radii={arm: radii for arm in ARMS},
            spindle_actuator=name2id(model, obj.mjOBJ_ACTUATOR, names.scoped(grinder, GRINDER, SPINDLE_JOINT)),
            spindle_dof=int(model.jnt_dofadr[spindle_joint]),
            cutter_geom=name2id(model, obj.mjOBJ_GEOM, names.scoped(grinder, GRINDER, CUTTER_GEOM)),
            gripper_actuator=name2id(model, obj.mjOBJ_ACTUATOR, names.scoped(gripper, GRIPPER, GRIPPER_CABLE)),
            plate_body=name2id(model, obj.mjOBJ_BODY, PLATE_BODY),
            sample_body=name2id(model, obj.mjOBJ_BODY, SAMPLE_BODY),
            sample_weld=name2id(model, obj.mjOBJ_EQUALITY, SAMPLE_WELD),
            geom_kind=_geom_kinds(model, grinder, gripper),
        )


def _geom_kinds(model: mujoco.MjModel, grinder: str, gripper: str) -> NDArray[np.int64]:
    kind = np.full(model.ngeom, int(GeomKind.OTHER), dtype=np.int64)
    cutter = names.scoped(grinder, GRINDER, CUTTER_GEOM)
    gripper_prefix = names.scoped(gripper, GRIPPER, "")
    arm_prefixes = [(names.scoped(arm, ""), int(GeomKind.of_arm(arm))) for arm in ARMS]
    for g in range(model.ngeom):
        body = model.body(model.geom_bodyid[g]).name
        if model.geom(g).name == cutter:
            kind[g] = GeomKind.CUTTER
        elif body.startswith(gripper_prefix):
            kind[g] = GeomKind.GRIPPER
        else:
            for prefix, value in arm_prefixes:
                if body.startswith(prefix):
                    kind[g] = value
                    break
    return kind
