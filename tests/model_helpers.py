"""Test-only helpers for the model tests (not part of the package)."""

from __future__ import annotations

from continuum_sim.geometry import ArmGeometry
from continuum_sim.model.arm import arm_collision_bits
from continuum_sim.model.options import ModelOptions, model_geometry
from continuum_sim.model.scene import mjcf  # dm_control's, imported after the GL backend choice

import mujoco  # noqa: E402


def compile_root(root: mjcf.RootElement) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())


def rigid_arm(geometry: ArmGeometry, options: ModelOptions, name: str, tool: str) -> mjcf.RootElement:
    """A straight, jointless stand-in with the arm builder's interface (``base``,
    ``tool_mount`` at the tip, ``tcp``): a kinematic carrier for tools in tests."""
    geometry = model_geometry(geometry, options)
    root = mjcf.RootElement(model=name)
    root.default.geom.contype, root.default.geom.conaffinity = arm_collision_bits(name)
    base = root.worldbody.add("body", name="base")
    radius = geometry.sections[-1].disk_diameter / 2
    base.add("geom", name="rod", type="cylinder", size=(0.005, geometry.length / 2), pos=(0, 0, geometry.length / 2), mass=0.1)
    tip = base.add("body", name="tip", pos=(0, 0, geometry.length))
    tip.add("geom", name="disk", type="cylinder", size=(radius, geometry.disk_thickness / 2), mass=0.01)
    tip.add("site", name="tool_mount")
    tip.add("site", name="tcp", pos=(0, 0, geometry.tools.length(tool)))
    return root


def carry_with_mocap(root: mjcf.RootElement, arm: str, anchor_height: float) -> mjcf.Element:
    """Give the ``arm`` stand-in a free joint welded to a new mocap body; returns the mocap.

    A mocap body itself has no velocity, so friction cannot drag things along with it;
    welding a free body to it gives the tool real velocities (what a grasp needs).
    """
    frame = root.find("attachment_frame", arm)
    frame.add("freejoint")
    target = root.worldbody.add("body", name=f"{arm}_target", mocap=True, pos=frame.pos)
    # Anchored near the tool: a weld anchored far from the load lets it swing.
    root.equality.add(
        "weld", body1=target, body2=root.find("body", f"{arm}/base"), anchor=(0, 0, anchor_height), solref=(0.004, 1.0)
    )
    return target


def contacts_on_a_plane(cone: str) -> mujoco.MjModel:
    """Three free bodies (condim 3, 1, 6) resting on a plane: contacts of every kind, for the contact-force tests."""
    return mujoco.MjModel.from_xml_string(f"""<mujoco><option cone="{cone}" timestep="0.002"/><worldbody>
      <geom type="plane" size="1 1 0.1"/>
      <body pos="0 0 0.05"><freejoint/><geom type="box" size="0.05 0.04 0.03" condim="3"/></body>
      <body pos="0.3 0 0.05"><freejoint/><geom type="sphere" size="0.04" condim="1"/></body>
      <body pos="-0.3 0 0.05" euler="0 20 10"><freejoint/><geom type="box" size="0.03 0.03 0.03" condim="6"/></body>
    </worldbody></mujoco>""")
