"""The replay plant: one arm of the scenario's model, and how recorded commands drive it.

Replays are kept cheap: one arm (no plate, no second arm), mounted where the layout puts
it, with its tool (the tool's mass is a plant parameter), tool-centre pose and cable
tension sensors that ``mujoco.rollout`` records every step.

``cable_controls`` is the one place that maps recorded cable set-points onto the model's
actuators. The actuators are tension-only cables (EA/L springs, or the lumped servo) whose
control is the motor position along the cable; a recorded set-point is the displacement
Δl from the straight-arm length (SPEC §2), calibrated like the package's own open-loop
controller: at Δl = 0 on a straight arm every cable pulls ``control.pretension``. When the
plant's actuation changes, only this function changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from ..configio import ConfigError
from ..kinematics import straight_cable_lengths
from ..model import names
from ..model.options import model_geometry
from ..scenario.config import ScenarioConfig

Array = NDArray[np.float64]


@dataclass
class ReplayModel:
    """A compiled replay model and where its inputs and outputs live."""

    model: mujoco.MjModel
    arm: str
    tool: str
    cable_actuators: NDArray[np.int_]
    gripper_actuator: int  # -1 when the arm has no gripper
    spindle_actuator: int  # -1 when the arm has no grinder
    sensor_pos: slice  # tool-centre position (3)
    sensor_quat: slice  # tool frame quaternion (4, w x y z)
    sensor_tension: slice  # cable actuator forces (≤ 0; tension = −force)


def resolve_tool(config: ScenarioConfig, arm: str, tool: str) -> str:
    return config.layout.mount(arm).tool if tool == "auto" else tool


def build_replay_model(config: ScenarioConfig, arm: str, tool: str = "auto", gravity: bool = True) -> ReplayModel:
    """The arm ``arm`` of ``config`` alone, at its layout mount, with ``tool`` and sensors."""
    from dm_control import mjcf

    from ..model import tools as tools_mod
    from ..model.arm import apply_simulation_options, build_arm

    tool = resolve_tool(config, arm, tool)
    options = config.model
    geometry = config.arm
    root = mjcf.RootElement(model=f"replay_{arm}")
    apply_simulation_options(root, options)
    if not gravity:
        root.option.gravity = (0.0, 0.0, 0.0)
    mount = config.layout.mount(arm)
    site = root.worldbody.add("site", name=f"{arm}_mount", pos=mount.position, size=(0.004,))
    arm_model = build_arm(geometry, options, arm, tool)
    site.attach(arm_model)
    plate = config.layout.plate
    tool_model = tools_mod.build_tool(tool, model_geometry(geometry, options), options, config.scene.tools,
                                      plate.kerf_width)
    if tool_model is not None:
        arm_model.find("site", "tool_mount").attach(tool_model)
    n_cables = geometry.n_cables
    root.sensor.add("framepos", name="tcp_pos", objtype="site", objname=names.scoped(arm, names.TCP_SITE))
    root.sensor.add("framequat", name="tcp_quat", objtype="site", objname=names.scoped(arm, names.TCP_SITE))
    for k in range(geometry.n_sections):
        for c in range(3):
            root.sensor.add("actuatorfrc", name=f"force_{k}_{c}", actuator=names.scoped(arm, names.cable(k, c)))
    model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())

    def act(name: str) -> int:
        return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name))

    cables = np.array([act(names.scoped(arm, names.cable(k, c))) for k in range(geometry.n_sections) for c in range(3)])
    if np.any(cables < 0):
        raise ConfigError("model.tendons", "the replay needs the cable actuators (model.tendons = true)")
    return ReplayModel(model, arm, tool, cables, act(f"{arm}/{tools_mod.GRIPPER}/{tools_mod.GRIPPER_CABLE}"),
                       act(f"{arm}/{tools_mod.GRINDER}/{tools_mod.SPINDLE_JOINT}"),
                       slice(0, 3), slice(3, 7), slice(7, 7 + n_cables))


def cable_controls(config: ScenarioConfig, delta: Array) -> Array:
    """Actuator controls (cable lengths, m) for recorded set-points ``delta`` (…, n_cables).

    ctrl = straight length + Δl − pretension/k: the open-loop controller's calibration,
    so Δl = 0 on the straight arm holds every cable at ``control.pretension`` (k: the
    cable's stiffness, EA/L for elastic cables, ``cable_kp`` for the lumped servo). The
    control is the motor position along the cable; the replay takes the motor as
    reaching its set-point (the encoder loop's integral action removes the load droop),
    so the motor loop's own lag (≈ 3 Hz bandwidth, docs/plant.md) is not replayed.
    """
    from ..model.cable_elasticity import pretension_offsets

    geometry = model_geometry(config.arm, config.model)
    straight = straight_cable_lengths(geometry)
    delta = np.asarray(delta, dtype=float)
    if delta.shape[-1] != straight.size:
        raise ConfigError("arm.sections", f"the recording has {delta.shape[-1]} cables, the configured arm {straight.size}")
    return straight + delta - pretension_offsets(config.arm, config.model, config.control.pretension)


def control_matrix(config: ScenarioConfig, plant: ReplayModel, delta: Array, gripper: Array | None,
                   spindle: Array | None) -> Array:
    """Full actuator-control rows (…, nu) for the recorded inputs (tools idle when absent)."""
    shape = delta.shape[:-1]
    ctrl = np.zeros((*shape, plant.model.nu))
    ctrl[..., plant.cable_actuators] = cable_controls(config, delta)
    if plant.gripper_actuator >= 0:
        ctrl[..., plant.gripper_actuator] = 0.0 if gripper is None else gripper
    if plant.spindle_actuator >= 0:
        ctrl[..., plant.spindle_actuator] = 0.0 if spindle is None else spindle
    return ctrl
