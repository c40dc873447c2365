"""A uniform elastic rod built by the arm's own backbone builder (validation subject).

The rod is the same chain of nodes and elastic joints as the arm (``build_backbone``),
with the stiffness and mass of a solid circular rod instead of flexure-hinged disks, so
comparing it with beam theory and a Cosserat-rod solver validates the arm's spine.
Discretisation (n links of pitch h = L/n, node i at s = i·h, joint i at s = (i − ½)h):

* joint i stands for the rod piece [(i−1)h, i·h]: bending stiffness EI/h, twist
  stiffness GJ/h. Joint kinds (``RodJoint``):
  - ``ball``: MuJoCo's isotropic ball spring, ½(EI/h)|ψ|² in the rotation vector ψ. Exact
    to O(1/n²) for the centreline, but twist is as stiff as bending (GJ = EI). Under
    world-fixed loads the centreline of a rod with isotropic bending does not depend on
    GJ (the twisting moment M·t is set by statics and only spins the cross-section about
    the tangent), so this is enough for shapes; only the material frame's twist is off.
  - ``ball_twist``: the ball joint preceded by a twist hinge of stiffness
    k_b·k_t/(k_b − k_t) in series, so the twist compliance is 1/k_b + 1/k_c = h/GJ while
    bending is untouched (needs GJ < EI, i.e. ν > 0). The energy then equals
    ½(EI κ² + GJ τ²)h up to fourth-order terms, so frames converge at O(1/n²) too. The
    two twist dofs move one body, so the hinge carries the node's polar inertia as
    armature to keep the mass matrix regular (dynamics only; statics ignore it).
  - ``hinge_triple``: Rx·Ry·Rz hinges with EI/h, EI/h, GJ/h. Euler angles read the twist
    as c = τh − κ₁κ₂h²/2, an O(1/n) error in every 3-D bend (measured: tip errors
    halve, not quarter, when n doubles); kept because the arm backbone offers it.
  - ``hinge_pair``: Rx·Ry, twist locked.
* node i carries the mass of the rod piece around it, ρA·h, the tip node half of it
  (its piece ends at s = L); every node's centre of mass is its origin, so a force
  applied there needs no lever-arm correction.

The clamp (node 0, body ``base``) sits at the world origin and the rod lies along +x,
the SoRoSim file frame; body ``disk_i`` is node i. Gravity is off in the built model:
set ``model.opt.gravity`` per load case.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..configio import ConfigError, require_int, require_range
from .backbone import LinkSpec, build_backbone

Array = NDArray[np.float64]
RodJoint = Literal["ball", "ball_twist", "hinge_pair", "hinge_triple"]

# Clamp frame in the world: +90° about y, mapping the backbone's z onto world +x.
_BASE_ROTATION = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


@dataclass(frozen=True)
class RodSpec:
    """A solid, uniform, straight rod of circular cross-section, and its discretisation."""

    length: float  # m
    radius: float  # m
    youngs_modulus: float  # Pa
    poisson_ratio: float
    density: float  # kg/m³
    n_links: int = 20
    joint: RodJoint = "ball_twist"
    damping: float = 0.0  # N·m·s/rad per joint (dynamics only)
    timestep: float = 1e-4  # s

    def __post_init__(self) -> None:
        require_range("length", self.length, 0.0, 100.0)
        require_range("radius", self.radius, 0.0, self.length / 2.0)
        require_range("youngs_modulus", self.youngs_modulus, 0.0, 1e13)
        require_range("poisson_ratio", self.poisson_ratio, -1.0, 0.5, high_inclusive=False)
        require_range("density", self.density, 0.0, 1e5)
        require_int("n_links", self.n_links, 1, 1000)
        if self.joint not in get_args(RodJoint):
            raise ConfigError("joint", f"must be one of {', '.join(get_args(RodJoint))} (got {self.joint!r})")
        if self.joint == "ball_twist" and not self.poisson_ratio > 0.0:
            raise ConfigError("poisson_ratio", f"must be > 0 for joint 'ball_twist' (GJ < EI) (got {self.poisson_ratio!r})")
        require_range("damping", self.damping, 0.0, 1e6, low_inclusive=True)
        require_range("timestep", self.timestep, 0.0, 0.01)

    # ------------------------------------------------------------ section properties
    @property
    def area(self) -> float:
        return math.pi * self.radius**2

    @property
    def bending_rigidity(self) -> float:
        """EI (N·m²), I = πr⁴/4."""
        return self.youngs_modulus * math.pi * self.radius**4 / 4.0

    @property
    def torsional_rigidity(self) -> float:
        """GJ (N·m²), J = πr⁴/2, G = E/(2(1+ν))."""
        shear = self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))
        return shear * math.pi * self.radius**4 / 2.0

    @property
    def mass_per_length(self) -> float:
        return self.density * self.area

    @property
    def pitch(self) -> float:
        return self.length / self.n_links

    def links(self) -> list[LinkSpec]:
        h = self.pitch
        common = dict(
            pitch=h,
            radius=self.radius,
            half_length=h / 2.0,
            bending_stiffness=self.bending_rigidity / h,
            twist_stiffness=self.torsional_rigidity / h,
            damping=self.damping,
            shape="capsule",
        )
        inner = LinkSpec(mass=self.mass_per_length * h, **common)  # type: ignore[arg-type]
        tip = LinkSpec(mass=self.mass_per_length * h / 2.0, **common)  # type: ignore[arg-type]
        return [inner] * (self.n_links - 1) + [tip]


def build_rod(spec: RodSpec):
    """MJCF root of the rod clamped at the origin along +x; gravity off, no contacts."""

    from dm_control import mjcf

    root = mjcf.RootElement(model="rod")
    root.compiler.angle = "radian"
    root.option.timestep = spec.timestep
    root.option.integrator = "implicitfast"
    root.option.gravity = (0.0, 0.0, 0.0)
    root.default.geom.contype = 0
    root.default.geom.conaffinity = 0
    base = root.worldbody.add("body", name="base", xyaxes=(*_BASE_ROTATION[:, 0], *_BASE_ROTATION[:, 1]))
    links = spec.links()
    backbone_joint = "ball" if spec.joint == "ball_twist" else spec.joint
    bodies = build_backbone(base, links, backbone_joint, rgba=(0.55, 0.6, 0.7, 1.0))
    if spec.joint == "ball_twist":
        k_bend, k_twist = links[0].bending_stiffness, links[0].twist_stiffness
        for i, (body, link) in enumerate(zip(bodies, links), start=1):
            body.insert(  # MuJoCo allows hinges before a ball joint in a body, not after
                "joint",
                0,
                name=f"joint_{i}_twist",
                type="hinge",
                axis=(0.0, 0.0, 1.0),
                pos=(0.0, 0.0, -link.pitch / 2.0),
                stiffness=k_bend * k_twist / (k_bend - k_twist),
                damping=link.damping,
                armature=link.mass * link.radius**2 / 2.0,
            )
    return root


def compile_rod(spec: RodSpec):
    """The compiled ``mujoco.MjModel`` of ``build_rod(spec)``."""
    import mujoco

    root = build_rod(spec)
    return mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())


def node_body_ids(model, n_links: int, prefix: str = "") -> np.ndarray:
    """Body ids of nodes 0 (the clamp ``base``) … n (the tip)."""
    import mujoco

    names = [f"{prefix}base"] + [f"{prefix}disk_{i}" for i in range(1, n_links + 1)]
    ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) for name in names])
    if (ids < 0).any():
        raise KeyError(f"rod node {names[int(np.argmin(ids))]!r} not found")
    return ids


def apply_node_wrench(model, data, body: int, force: ArrayLike, torque: ArrayLike) -> None:
    """Set a world-frame force (at the node's origin) and torque on ``body`` via xfrc_applied.

    MuJoCo applies ``xfrc_applied`` at the body's centre of mass; the rod's nodes have
    theirs at the origin, which is checked here rather than assumed.
    """
    if not np.allclose(model.body_ipos[body], 0.0, atol=1e-12):
        raise ValueError(f"body {body} has its centre of mass off its origin; a force there would add a moment")
    data.xfrc_applied[body, :3] = force
    data.xfrc_applied[body, 3:] = torque


def node_poses(data, ids: np.ndarray) -> tuple[Array, Array]:
    """World positions (k, 3) and rotations (k, 3, 3) of the given nodes' cross-sections.

    Rotations are material frames that equal the identity at the clamp (tangent = first
    column, as in the SoRoSim files), not MuJoCo's body frames (tangent = z).
    """
    to_material = _BASE_ROTATION.T
    return data.xpos[ids].copy(), data.xmat[ids].reshape(-1, 3, 3) @ to_material


def centreline(spec: RodSpec, positions: Array, rotations: Array, s: ArrayLike) -> Array:
    """Points of the chain's centreline at arc lengths ``s`` (m).

    ``rotations`` are ``node_poses``' material frames. Node i's rigid piece spans
    s ∈ [i·h − h/2, i·h + h/2] along its tangent (joints sit at the ends), so the
    centreline is exact, not interpolated.
    """
    s = np.clip(np.asarray(s, dtype=float), 0.0, spec.length)
    i = np.clip(np.rint(s / spec.pitch).astype(int), 0, spec.n_links)  # type: ignore[operator]
    offset = s - i * spec.pitch
    return positions[i] + offset[..., None] * rotations[i][..., :, 0]
