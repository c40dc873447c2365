"""The tool a static evaluation carries: the real tool's mass, centre of mass and inertia.

The static evaluations (``gravity_sag``, ``tip_deflection``) use the single-arm model,
which has no tool bodies; the tools (80 g grinder, 60 g gripper by default) cause about
half of the arm's gravity sag, so leaving them out understated it. The payload is taken
from the very tool model the task scene attaches (``model.tools.build_tool``), compiled
alone at its rest pose and lumped into one rigid body on the tip disk: the same mass, centre of
mass and inertia about it (its joints — spindle, jaws — held at their rest positions).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from dm_control import mjcf

from ..model import names
from ..model.arm import arm_collision_bits
from ..model.options import model_geometry

PAYLOAD_BODY = "payload"


@dataclass(frozen=True)
class Payload:
    """A rigid payload in the tool-mount frame: mass (kg), centre of mass (m), inertia about it (kg·m²)."""

    tool: str
    mass: float
    com: tuple[float, float, float]
    inertia: tuple[float, float, float, float, float, float]  # xx, yy, zz, xy, xz, yz

    @property
    def weight_moment_arm(self) -> float:
        """Distance of the centre of mass from the tool mount along the tool axis (m)."""
        return self.com[2]


def tool_payload(config, tool: str) -> Payload:
    """The payload of ``tool`` ("grinder", "gripper", "none") for a scenario config."""
    from ..model import tools as tools_mod

    if tool == "none":
        return Payload("none", 0.0, (0.0, 0.0, 0.0), (0.0,) * 6)
    options = config.model
    plate = config.layout.plate
    tool_model = tools_mod.build_tool(
        tool,
        model_geometry(config.arm, options),
        options,
        config.scene.tools,
        plate.kerf_width,
        arm_collision_bits(names.SINGLE_ARM),
        pad_tilt_deg=config.layout.grasp.tilt_deg,
    )
    root = mjcf.RootElement(model="payload")
    root.compiler.angle = "radian"
    root.worldbody.add("site", name="mount").attach(tool_model)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    masses = model.body_mass[1:]
    total = float(masses.sum())
    com = (masses[:, None] * data.xipos[1:]).sum(axis=0) / total
    inertia = np.zeros((3, 3))
    for b in range(1, model.nbody):
        rot = data.ximat[b].reshape(3, 3)
        d = data.xipos[b] - com
        inertia += rot @ np.diag(model.body_inertia[b]) @ rot.T
        inertia += model.body_mass[b] * (d @ d * np.eye(3) - np.outer(d, d))
    full = (
        float(inertia[0, 0]),
        float(inertia[1, 1]),
        float(inertia[2, 2]),
        float(inertia[0, 1]),
        float(inertia[0, 2]),
        float(inertia[1, 2]),
    )
    return Payload(tool, total, (float(com[0]), float(com[1]), float(com[2])), full)


def add_payload(root, arm: str, payload: Payload) -> None:
    """Fix ``payload`` as a body on ``arm``'s tip disk (the body that carries its ``tool_mount`` site)."""
    if payload.mass <= 0.0:
        return
    site = names.scoped(arm, names.TOOL_MOUNT_SITE)
    mount = root.find("site", site)
    if mount is None:
        raise ValueError(f"model has no {site} site for the {payload.tool} payload")
    body = mount.parent.add("body", name=PAYLOAD_BODY, pos=mount.pos)
    body.add("inertial", pos=payload.com, mass=payload.mass, fullinertia=payload.inertia)
