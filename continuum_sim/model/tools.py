"""End effectors: the grinder (left arm) and the cable-closed two-jaw gripper (right arm).

Pure PyMJCF builders. Each returns a model whose worldbody origin is the arm's tip frame
(the last disk centre, z along the arm); the scene attaches it at ``<arm>/tool_mount``.
The tool centre point lies on the tool's z axis at ``geometry.tools.length(tool)``,
which is where the arm builder puts its ``<arm>/tcp`` site, so planner and model agree.

Grinder: a housing welded to the last disk and a spindle body on a hinge about the tool
z axis (the spindle motor sits in the pack and drives a flexible shaft, so only a small
mass rides on the arm). Its speed loop is a PI with a torque limit: the P part is a
MuJoCo velocity actuator with a force range, the I part ``plant.spindle.SpindleDrive`` (which also
reports a stall). The cutting geom ``cutter`` is a cylinder of the kerf width whose tip
face centre is the TCP; it belongs to the housing body (the spinning ``cutter_visual``
of the same shape is what one sees) and collides with nothing: ``plant.cutter.FoamCutter``
intersects it with the foam's voxels and applies the cutting force.

Gripper: a palm and two jaws on slide joints along the tool x axis (q = 0 open, q > 0
closing). One cable closes both jaws through a fixed tendon
``cable = −(q_a + q_b)`` (0 when open, −2·travel fully closed), so a jaw that meets the
object first stops while the other keeps closing: a self-centring differential like a
cable looped over both jaws. Springs in the slide joints open the jaws; the cable's
actuator is a tension-only position loop (force range [−F, 0]) like the arm cables.
"""

from __future__ import annotations

import math

from dm_control import mjcf

from ..configio import ConfigError, require_positive
from ..geometry import ArmGeometry
from .options import ModelOptions
from .scene_options import ToolOptions

GRINDER = "grinder"
GRIPPER = "gripper"
SPINDLE_JOINT = "spindle"  # hinge of the grinder spindle, and its velocity actuator's name
CUTTER_GEOM = "cutter"
SPINDLE_BODY = "spindle"
GRIPPER_CABLE = "cable"  # fixed tendon closing the jaws, and its actuator's name
JAW_JOINTS = ("jaw_a", "jaw_b")
PAD_GEOMS = ("pad_a", "pad_b")

# Collision priority: the foam's (soft) contact wins over everything else it touches.
JAW_OPEN_REST = 5e-4  # m, where an unloaded spring (no preload) holds an open jaw (from its stop, closing)


def jaw_spring_reference(tools: ToolOptions) -> float:
    """The jaw spring's rest position (m, closing positive): behind the open stop by
    preload / stiffness, so an open jaw is pressed onto its stop with ``gripper_preload``.

    Without a preload the jaw rests just inside its stop (JAW_OPEN_REST), off the limit
    constraint — but then nothing but 20 N/m holds a 24 g jaw against gravity.
    """
    if tools.gripper_preload <= 0.0 or tools.gripper_spring <= 0.0:
        return JAW_OPEN_REST
    return -tools.gripper_preload / tools.gripper_spring
PAD_PRIORITY = 2  # the gripper pads' (near-hard) contact wins over the foam's
FOAM_PRIORITY = 1


def build_grinder(
    geometry: ArmGeometry,
    options: ModelOptions,
    tools: ToolOptions,
    cutter_diameter: float,
    collision: tuple[int, int] = (1, 1),
) -> mjcf.RootElement:
    """The grinder: housing + spinning cutter whose tip face centre is the grinder TCP.

    ``cutter_diameter`` is the kerf width. ``collision`` is the carrying arm's (contype,
    conaffinity): the housing never collides with its own arm; the cutter with nothing.
    """
    length = geometry.tools.grinder_length
    half_disk = geometry.disk_thickness / 2
    require_positive("cutter_diameter", cutter_diameter)
    if tools.cutter_length >= length - half_disk - 0.004:
        raise ConfigError(
            "tools.cutter_length",
            f"must be < grinder_length − disk_thickness/2 − 4 mm = {length - half_disk - 0.004:g} m "
            f"to leave room for the housing (got {tools.cutter_length:g})",
        )
    if tools.housing_radius >= geometry.sections[-1].disk_diameter / 2 + 0.01:
        raise ConfigError("tools.housing_radius", "must not exceed the distal disk radius by more than 10 mm")
    radius = cutter_diameter / 2
    cutter_base = length - tools.cutter_length
    housing_top = cutter_base - 0.003  # a short bare shaft between housing and cutter
    housing_mass = tools.grinder_housing_fraction * options.grinder_mass
    spindle_mass = options.grinder_mass - housing_mass
    shaft_radius = min(0.002, 0.6 * radius)

    root = mjcf.RootElement(model=GRINDER)
    root.default.geom.rgba = (0.55, 0.57, 0.6, 1.0)
    root.default.geom.contype, root.default.geom.conaffinity = collision
    housing = root.worldbody.add("body", name="housing")
    housing.add(
        "geom",
        name="housing",
        type="cylinder",
        size=(tools.housing_radius, (housing_top - half_disk) / 2),
        pos=(0, 0, (housing_top + half_disk) / 2),
        mass=housing_mass,
        rgba=(0.2, 0.22, 0.25, 1.0),
    )
    spindle = housing.add("body", name=SPINDLE_BODY, pos=(0, 0, housing_top))
    spindle.add(
        "joint",
        name=SPINDLE_JOINT,
        type="hinge",
        axis=(0, 0, 1),
        armature=tools.spindle_armature,
        damping=0.0,
    )
    shaft_mass = tools.grinder_shaft_fraction * spindle_mass
    spindle.add(
        "geom",
        name="shaft",
        type="cylinder",
        size=(shaft_radius, (cutter_base - housing_top) / 2),
        pos=(0, 0, (cutter_base - housing_top) / 2),
        mass=shaft_mass,
        contype=0,
        conaffinity=0,
    )
    cutter_centre = length - tools.cutter_length / 2
    spindle.add(
        "geom",
        name="cutter_visual",
        type="cylinder",
        size=(radius, tools.cutter_length / 2),
        pos=(0, 0, cutter_centre - housing_top),
        mass=spindle_mass - shaft_mass,
        contype=0,
        conaffinity=0,
        rgba=(0.85, 0.75, 0.3, 1.0),
    )
    # A stripe so the spin is visible in videos; no collision, no mass.
    spindle.add(
        "geom",
        name="stripe",
        type="box",
        size=(radius * 1.03, 0.0006, tools.cutter_length / 2 * 0.98),
        pos=(0, 0, cutter_centre - housing_top),
        contype=0,
        conaffinity=0,
        mass=0,
        rgba=(0.3, 0.2, 0.1, 1.0),
        group=1,
    )
    # The cutting geom: where the cutter is, not a contact. It sits on the housing (the cutting
    # force, applied by ``plant.cutter.FoamCutter`` to the housing body, loads the arm through the
    # bearings) and collides with nothing: the foam it meets is the cutter's voxel material,
    # not MuJoCo geoms. Massless, hidden (group 3) under the spinning visual cutter.
    housing.add(
        "geom",
        name=CUTTER_GEOM,
        type="cylinder",
        size=(radius, tools.cutter_length / 2),
        pos=(0, 0, cutter_centre),
        mass=0,
        contype=0,
        conaffinity=0,
        rgba=(0.85, 0.75, 0.3, 0.4),
        group=3,
    )
    spindle.add("site", name="tip", pos=(0, 0, length - housing_top), size=(0.0015,), rgba=(1, 0, 0, 1))
    # The proportional part of the speed loop, integrated implicitly by MuJoCo (an explicit
    # P term on the 1e-5 kg·m² rotor would be unstable at the scenario's 4 ms step); the
    # integral part is added to the set-point by ``plant.spindle.SpindleDrive``; the torque limit is the
    # actuator's force range.
    root.actuator.add(
        "velocity",
        name=SPINDLE_JOINT,
        joint=spindle.find("joint", SPINDLE_JOINT),
        kv=tools.spindle_kv,
        ctrlrange=(0.0, tools.spindle_max_speed),
        ctrllimited=True,
        forcerange=(-tools.spindle_max_torque, tools.spindle_max_torque),
        forcelimited=True,
    )
    return root


def build_gripper(
    geometry: ArmGeometry,
    options: ModelOptions,
    tools: ToolOptions,
    collision: tuple[int, int] = (1, 1),
    pad_tilt_deg: float = 0.0,
) -> mjcf.RootElement:
    """The two-jaw gripper: pads centred on the TCP, jaws closing along the tool x axis.

    ``collision`` is the carrying arm's (contype, conaffinity), as for the grinder.
    ``pad_tilt_deg``: the pads are turned by this angle about the tool y axis so that they
    lie flat on a plate whose normal is that far from the closing axis (the task's grasp
    tilt, ``GraspLayout.tilt_deg``). Untilted pads touch such a plate on one edge each: a
    line contact the sample pivots about, and a wedge that squeezes it out.
    """
    length = geometry.tools.gripper_length
    half_disk = geometry.disk_thickness / 2
    pad_half = tools.gripper_pad_length / 2
    palm_half_z = 0.008
    palm_top = half_disk + 2 * palm_half_z
    if length - pad_half <= palm_top + 0.004:
        raise ConfigError(
            "tools.gripper_pad_length",
            f"pads would reach into the palm: need gripper_length − pad_length/2 > {palm_top + 0.004:g} m",
        )
    finger_t = 0.004  # finger plate thickness along x
    pad_t = tools.gripper_pad_thickness
    # The fingers end at the pad centre line: beyond it a finger tilted against the plate
    # would reach the plate before its pad does.
    finger_top = length
    finger_half_z = (finger_top - palm_top) / 2
    finger_x = tools.gripper_open_gap / 2 + pad_t + finger_t / 2  # finger centre, open
    palm_half_x = finger_x + finger_t / 2 + 0.002
    palm_half_y = tools.gripper_pad_width / 2 + 0.002
    palm_mass = tools.gripper_palm_fraction * options.gripper_mass
    jaw_mass = (options.gripper_mass - palm_mass) / 2
    tilt = math.radians(pad_tilt_deg)
    pad_quat = (math.cos(-tilt / 2), 0.0, math.sin(-tilt / 2), 0.0)  # about tool y by −tilt

    root = mjcf.RootElement(model=GRIPPER)
    root.default.geom.contype, root.default.geom.conaffinity = collision
    palm = root.worldbody.add("body", name="palm")
    palm.add(
        "geom",
        name="palm",
        type="box",
        size=(palm_half_x, palm_half_y, palm_half_z),
        pos=(0, 0, half_disk + palm_half_z),
        mass=palm_mass,
        rgba=(0.2, 0.22, 0.25, 1.0),
    )
    for side, sign in (("a", 1.0), ("b", -1.0)):
        jaw = palm.add("body", name=f"jaw_{side}", pos=(sign * finger_x, 0, 0))
        jaw.add(
            "joint",
            name=f"jaw_{side}",
            type="slide",
            axis=(-sign, 0, 0),  # positive = closing
            range=(0.0, tools.gripper_jaw_travel),
            limited=True,
            stiffness=tools.gripper_spring,
            springref=jaw_spring_reference(tools),
            damping=tools.gripper_damping,
            armature=tools.gripper_jaw_armature,
            # A hard end stop: the default soft limit let a jaw overrun by 3 mm at full grip force.
            solreflimit=tools.gripper_stop_solref,
            solimplimit=(*tools.gripper_stop_solimp, 0.5, 2),
        )
        jaw.add(
            "geom",
            name=f"finger_{side}",
            type="box",
            size=(finger_t / 2, tools.gripper_pad_width / 2, finger_half_z),
            pos=(0, 0, palm_top + finger_half_z),
            mass=(1.0 - tools.gripper_pad_fraction) * jaw_mass,
            rgba=(0.55, 0.57, 0.6, 1.0),
        )
        jaw.add(
            "geom",
            name=f"pad_{side}",
            type="box",
            size=(pad_t / 2, tools.gripper_pad_width / 2, pad_half),
            # Turned about the centre of its gripping face, which stays on the closing line.
            pos=(-sign * (finger_t / 2 + pad_t) + sign * pad_t / 2 * math.cos(tilt), 0, length + sign * pad_t / 2 * math.sin(tilt)),
            quat=pad_quat,
            mass=tools.gripper_pad_fraction * jaw_mass,
            friction=(tools.pad_friction, tools.pad_torsional_friction, tools.pad_rolling_friction),
            priority=PAD_PRIORITY,
            solref=tools.pad_solref,
            solimp=tools.pad_solimp,
            rgba=(0.15, 0.15, 0.15, 1.0),
        )
    palm.add("site", name="tip", pos=(0, 0, length), size=(0.0015,), rgba=(1, 0, 0, 1))
    cable = root.tendon.add("fixed", name=GRIPPER_CABLE)
    for name in JAW_JOINTS:
        cable.add("joint", joint=root.find("joint", name), coef=-1.0)
    root.actuator.add(
        "position",
        name=GRIPPER_CABLE,
        tendon=cable,
        kp=tools.gripper_kp,
        ctrlrange=(tools.gripper_cable_closed, 0.0),
        ctrllimited=True,
        forcerange=(-tools.gripper_max_force, 0.0),
        forcelimited=True,
    )
    return root


def build_tool(
    tool: str,
    geometry: ArmGeometry,
    options: ModelOptions,
    tools: ToolOptions,
    cutter_diameter: float,
    collision: tuple[int, int] = (1, 1),
    pad_tilt_deg: float = 0.0,
) -> mjcf.RootElement | None:
    """The named tool's model (``None`` for ``"none"``)."""
    if tool == GRINDER:
        return build_grinder(geometry, options, tools, cutter_diameter, collision)
    if tool == GRIPPER:
        return build_gripper(geometry, options, tools, collision, pad_tilt_deg)
    if tool == "none":
        return None
    raise ConfigError("tool", f"must be one of 'grinder', 'gripper', 'none' (got {tool!r})")
