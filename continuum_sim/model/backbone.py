"""A chain of rigid nodes joined by elastic joints: the spine of the arm and of test rods.

Node i sits ``pitch`` above node i−1 along the parent's z; its joint lies half-way
between them (SPEC §2: ``Trans(p/2) · R · Trans(p/2)``), so a chain of n nodes of pitch
L/n is exactly the discrete PCC model when bent uniformly. The same builder makes the
continuum arm (disks) and the uniform rods compared with SoRoSim (capsule links).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from ..configio import ConfigError

JointKind = Literal["ball", "hinge_pair", "hinge_triple"]
# hinge_pair: joint i (1-based) is Rx·Ry for odd i and Ry·Rx for even i (see _add_joints);
# hinge_triple: Rx·Ry·Rz on every joint, the twist hinge with its own spring.


@dataclass(frozen=True)
class LinkSpec:
    """One node of a backbone and the elastic joint that carries it."""

    pitch: float  # distance from the previous node along its z
    radius: float  # geom radius
    half_length: float  # geom half length along z
    mass: float
    bending_stiffness: float  # N·m/rad about x (and y unless bending_stiffness_y is given)
    twist_stiffness: float  # N·m/rad about z (hinge_triple only; a ball joint's spring is isotropic)
    damping: float
    armature: float = 0.0
    shape: Literal["cylinder", "capsule"] = "cylinder"
    bending_stiffness_y: float | None = None  # N·m/rad about y when the segment is anisotropic

    def __post_init__(self) -> None:
        for name in ("pitch", "radius", "half_length", "mass"):
            if not getattr(self, name) > 0:
                raise ConfigError(name, f"must be > 0 (got {getattr(self, name)!r})")
        for name in ("bending_stiffness", "twist_stiffness", "damping", "armature"):
            if not getattr(self, name) >= 0:
                raise ConfigError(name, f"must be >= 0 (got {getattr(self, name)!r})")
        if self.bending_stiffness_y is not None and not self.bending_stiffness_y >= 0:
            raise ConfigError("bending_stiffness_y", f"must be >= 0 (got {self.bending_stiffness_y!r})")

    @property
    def stiffness_y(self) -> float:
        """Bending stiffness about y (equal to x unless given)."""
        return self.bending_stiffness if self.bending_stiffness_y is None else self.bending_stiffness_y


def _add_joints(body, index: int, link: LinkSpec, kind: JointKind) -> None:
    pos = (0.0, 0.0, -link.pitch / 2.0)
    common = dict(pos=pos, damping=link.damping, armature=link.armature)
    if kind == "ball":
        # MuJoCo's ball-joint spring is isotropic: the mean bending stiffness, also in twist.
        stiffness = 0.5 * (link.bending_stiffness + link.stiffness_y)
        body.add("joint", name=f"joint_{index}", type="ball", stiffness=stiffness, **common)
        return
    if kind not in ("hinge_pair", "hinge_triple"):
        raise ConfigError("joint", f"must be 'ball', 'hinge_pair' or 'hinge_triple' (got {kind!r})")
    axes = [("x", (1, 0, 0), link.bending_stiffness), ("y", (0, 1, 0), link.stiffness_y)]
    if kind == "hinge_pair" and index % 2 == 0:
        # Alternate the order (x-y, y-x, …): a universal joint adds a second-order twist
        # ±ab/2 whose sign flips with the order, so consecutive joints cancel it.
        axes.reverse()
    if kind == "hinge_triple":
        # Rx·Ry·Rz on every joint (a twist DoF with its own spring absorbs the second-order twist).
        axes.append(("z", (0, 0, 1), link.twist_stiffness))
    for suffix, axis, stiffness in axes:
        body.add("joint", name=f"joint_{index}_{suffix}", type="hinge", axis=axis, stiffness=stiffness, **common)


def build_backbone(parent, links: Sequence[LinkSpec], joint: JointKind, *, rgba=(0.8, 0.8, 0.82, 1.0), material=None, first_index: int = 1) -> list:
    """Append a chain of bodies ``disk_<i>`` under ``parent``; returns the bodies in order."""
    bodies = []
    body = parent
    for offset, link in enumerate(links):
        index = first_index + offset
        body = body.add("body", name=f"disk_{index}", pos=(0.0, 0.0, link.pitch))
        _add_joints(body, index, link, joint)
        geom_kwargs = dict(name=f"disk_{index}", mass=link.mass, rgba=rgba)
        if material is not None:
            geom_kwargs["material"] = material
            geom_kwargs.pop("rgba")
        if link.shape == "cylinder":
            body.add("geom", type="cylinder", size=(link.radius, link.half_length), **geom_kwargs)
        else:
            body.add(
                "geom",
                type="capsule",
                fromto=(0.0, 0.0, -link.half_length, 0.0, 0.0, link.half_length),
                size=(link.radius,),
                **geom_kwargs,
            )
        bodies.append(body)
    return bodies
