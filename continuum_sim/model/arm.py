"""PyMJCF builder of one continuum arm: disks, flexure joints, cable sites, tendons, motors.

A pure function of (geometry, options): it holds no simulation state. Every disk carries
a site at each cable hole it has (proximal disks carry the holes of all cables passing
through), and each cable is a spatial tendon through its holes from the base plate to
the last disk of its section, so the tendon length is exactly SPEC §2's cable length
(the polyline of the closed-loop vectors l). Each cable is pulled by one tension-only
position actuator, force range [−Fmax, 0]: with ``cable_model = "elastic"`` its gain is
the cable's own axial stiffness EA/L (L = lead + in-arm path; ``motors.cable_stiffness``)
and its control the motor position (``plant.drive.MotorBank``); with ``"lumped"`` it is the
legacy P-only servo of gain ``cable_kp`` standing for motor and cable together.
"""

from __future__ import annotations

import math

import numpy as np

from ..configio import ConfigError
from ..geometry import ArmGeometry
from ..kinematics import straight_cable_lengths
from .backbone import LinkSpec, build_backbone
from .cable_elasticity import cable_stiffness, cable_velocity_gain
from .options import ModelOptions, model_geometry
from .stiffness import joint_stiffnesses

# Collision bits: an arm never collides with itself, but with the other arm and the world.
ARM_COLLISION_BITS = {"left": 2, "right": 4}
WORLD_COLLISION_BIT = 1
OTHER_ARM_BIT = 8
KERF_BIT = 16  # kerf cells: touched by arms and tools, never by the welded sample they surround


def kerf_collision_bits() -> tuple[int, int]:
    """(contype, conaffinity) of kerf cells: collide with arms and tools, not with world bodies.

    The sample sits 0.2 mm from the cells while welded to the plate; contacts between them
    would only fight the weld (and cost solver time every step).
    """
    return KERF_BIT, sum(ARM_COLLISION_BITS.values()) | OTHER_ARM_BIT


def arm_collision_bits(name: str) -> tuple[int, int]:
    """(contype, conaffinity) of an arm's geoms: collide with world and other arms only."""
    own = ARM_COLLISION_BITS.get(name, OTHER_ARM_BIT)
    others = sum(ARM_COLLISION_BITS.values()) + OTHER_ARM_BIT
    return own, WORLD_COLLISION_BIT | (others & ~own)


def section_links(geometry: ArmGeometry, options: ModelOptions) -> list[list[LinkSpec]]:
    """The backbone links of each section of the model (resampled when asked).

    Disk mass is the physical section's disk mass shared over the model's disks, so a
    resampled model keeps the arm's mass; stiffness and damping scale as n_model/n_phys.
    """
    model_geom = model_geometry(geometry, options)
    out = []
    for k, (phys, sec) in enumerate(zip(geometry.sections, model_geom.sections)):
        radius = sec.disk_diameter / 2.0
        disk_volume = math.pi * radius**2 * geometry.disk_thickness
        section_mass = phys.n_segments * geometry.material.density * disk_volume
        if geometry.backbone == "rod":
            section_mass += geometry.rod.density * math.pi * geometry.rod.radius**2 * phys.length
        kx, ky, kz = joint_stiffnesses(geometry, k, sec.n_segments, options.stiffness_scale)
        if options.joint == "hinge_triple" and not math.isfinite(kz):
            raise ConfigError("model.joint", "hinge_triple needs a twist spring; arm.central_joint = 'universal' blocks twist (use hinge_pair)")
        damping = options.joint_damping * sec.n_segments / phys.n_segments
        link = LinkSpec(
            pitch=sec.pitch,
            radius=radius,
            half_length=geometry.disk_thickness / 2.0,
            mass=section_mass / sec.n_segments,
            bending_stiffness=kx,
            bending_stiffness_y=ky,
            twist_stiffness=kz if math.isfinite(kz) else 0.0,
            damping=damping,
            armature=options.joint_armature,
        )
        out.append([link] * sec.n_segments)
    return out


def build_arm(geometry: ArmGeometry, options: ModelOptions, name: str, tool: str = "none"):
    """An arm model named ``name``; attach it with ``site.attach(build_arm(...))``.

    Bodies ``base``, ``disk_1`` … ``disk_N``; sites ``hole_<disk>_<cable>``, ``tool_mount``
    (tip frame) and ``tcp`` (tool length along the tip z); tendons and actuators
    ``cable_<section>_<c>`` (actuator control = commanded cable length, m).
    """

    from dm_control import mjcf

    if tool not in ("grinder", "gripper", "none"):
        raise ConfigError("tool", f"must be 'grinder', 'gripper' or 'none' (got {tool!r})")
    model_geom = model_geometry(geometry, options)
    root = mjcf.RootElement(model=name)
    contype, conaffinity = arm_collision_bits(name)
    root.default.geom.contype = contype
    root.default.geom.conaffinity = conaffinity
    root.asset.add("material", name="disk", rgba=(0.78, 0.80, 0.84, 1.0), specular=0.3, shininess=0.4)
    root.asset.add("material", name="base", rgba=(0.35, 0.37, 0.42, 1.0))

    holes = model_geom.cable_holes()
    cable_section = np.repeat(np.arange(model_geom.n_sections), 3)

    base = root.worldbody.add("body", name="base")
    base_radius = model_geom.sections[0].disk_diameter / 2.0
    base.add(
        "geom",
        name="base",
        type="cylinder",
        size=(base_radius, geometry.disk_thickness / 2.0),
        material="base",
        mass=geometry.material.density * math.pi * base_radius**2 * geometry.disk_thickness,
    )
    _add_hole_sites(base, 0, holes, range(model_geom.n_cables))

    links = section_links(geometry, options)
    joint_kind = options.joint
    parent = base
    disk_index = 1
    disk_section: list[int] = []
    for k, section_links_k in enumerate(links):
        bodies = build_backbone(parent, section_links_k, joint_kind, material="disk", first_index=disk_index)
        passing = [c for c in range(model_geom.n_cables) if cable_section[c] >= k]
        for body in bodies:
            _add_hole_sites(body, disk_index, holes, passing)
            disk_section.append(k)
            disk_index += 1
        parent = bodies[-1]

    tip = parent
    tip.add("site", name="tool_mount", pos=(0.0, 0.0, 0.0), size=(0.002,), rgba=(0.1, 0.6, 0.1, 0.0))
    tip.add("site", name="tcp", pos=(0.0, 0.0, geometry.tools.length(tool)), size=(0.003,), rgba=(1.0, 0.2, 0.2, 0.6))

    if options.tendons:
        straight = straight_cable_lengths(model_geom)
        stiffness = cable_stiffness(geometry, options)
        last_disk = np.cumsum([s.n_segments for s in model_geom.sections])
        for c in range(model_geom.n_cables):
            k, j = divmod(c, 3)
            cable = f"cable_{k}_{j}"
            tendon = root.tendon.add(
                "spatial", name=cable, width=0.0008, rgba=(0.95, 0.55, 0.1, 1.0), damping=options.cable_damping
            )
            for disk in range(int(last_disk[k]) + 1):
                tendon.add("site", site=f"hole_{disk}_{c}")
            root.actuator.add(
                "position",
                name=cable,
                tendon=cable,
                kp=float(stiffness[c]),
                kv=cable_velocity_gain(float(stiffness[c]), options),
                forcelimited=True,
                forcerange=(-options.cable_max_force, 0.0),
                ctrllimited=True,
                ctrlrange=(straight[c] - 0.15, straight[c] + 0.15),
            )
    return root


def _add_hole_sites(body, disk: int, holes: np.ndarray, cables) -> None:
    for c in cables:
        body.add("site", name=f"hole_{disk}_{c}", pos=holes[c], size=(0.0012,), rgba=(0.9, 0.5, 0.1, 0.0))


def apply_simulation_options(root, options: ModelOptions) -> None:
    """Global <option>/<compiler> settings; set once on the top-level model only."""
    root.option.timestep = options.timestep
    root.option.integrator = options.integrator
    # MuJoCo's soft friction creeps under a steady tangential load; a grasp held for tens
    # of seconds (the gripper on the welded sample) slid ~20 mm at impratio 10.
    root.option.cone = "elliptic"
    root.option.impratio = options.impratio
    root.option.jacobian = options.jacobian
    if not options.gravity:
        root.option.gravity = (0.0, 0.0, 0.0)
    root.compiler.angle = "radian"
    root.size.memory = "64M"


def build_single_arm_model(geometry: ArmGeometry, options: ModelOptions, tool: str = "none", gravity: bool = True):
    """A standalone arm mounted at the world origin (tests, benchmarks, `models/arm.xml`)."""
    from dm_control import mjcf

    root = mjcf.RootElement(model="single_arm")
    apply_simulation_options(root, options)
    if not gravity:
        root.option.gravity = (0.0, 0.0, 0.0)
    root.worldbody.add("light", pos=(0.0, -1.0, 1.5), dir=(0.0, 0.6, -0.8), diffuse=(0.8, 0.8, 0.8))
    mount = root.worldbody.add("site", name="mount_arm", pos=(0.0, 0.0, 0.0))
    mount.attach(build_arm(geometry, options, "arm", tool))
    return root
