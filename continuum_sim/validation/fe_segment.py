"""An independent finite-element model of one flexure segment: the check on ``model.stiffness``.

Written for validation only; it shares no formula with ``continuum_sim.model.stiffness``.
Each leaf is a chain of 3-D Timoshenko frame elements (12 DoF: axial, St Venant
torsion, bending in both principal planes with shear deformation) along its free length,
its principal axes radial (thickness t) and tangential (width w). The torsion constant
comes from the exact series solution for a rectangle and the shear coefficient from
Cowper's formula. The leaves' lower ends are clamped to the fixed lower disk; their upper
ends are tied rigidly to the upper disk, whose reference node sits at the joint centre
(mid-gap on the axis). The central joint is a constraint on that node: ball — its
translations are zero and its three rotations free; universal — the twist rotation is
zero too. A unit moment about x, y and z at the reference node gives the compliance;
its inverse is the segment's rotational stiffness about the joint centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from ..configio import require_int, require_positive, require_range
from ..plant.leaf_rod import LeafSection  # the leaf cross-section (area, second moments, St Venant J): one definition

if TYPE_CHECKING:
    from ..geometry import ArmGeometry, SectionGeometry


def rectangle_torsion_constant(a: float, b: float, terms: int = 50) -> float:
    """St Venant torsion constant of an a×b rectangle, exact series (Timoshenko & Goodier §109).

    J = (1/3)·B·T³·[1 − (192/π⁵)(T/B)·Σ_{n odd} tanh(nπB/2T)/n⁵], B ≥ T.
    """
    big, small = max(a, b), min(a, b)
    total = 0.0
    for k in range(terms):
        n = 2 * k + 1
        total += math.tanh(n * math.pi * big / (2.0 * small)) / n**5
    return big * small**3 / 3.0 * (1.0 - 192.0 / math.pi**5 * (small / big) * total)


def frame_element_stiffness(
    length: float,
    e: float,
    g: float,
    area: float,
    iy: float,
    iz: float,
    j: float,
    kappa: float,
) -> np.ndarray:
    """12×12 local stiffness of a 3-D Timoshenko frame element (Przemieniecki).

    Local DoF order per node: u, v, w, θx, θy, θz; x along the element; ``iz`` governs
    bending in the x–y plane (v, θz), ``iy`` in the x–z plane (w, θy).
    """
    ll = length
    k = np.zeros((12, 12))
    ea, gj = e * area / ll, g * j / ll
    for a, b, val in (
        (0, 0, ea),
        (6, 6, ea),
        (0, 6, -ea),
        (3, 3, gj),
        (9, 9, gj),
        (3, 9, -gj),
    ):
        k[a, b] = k[b, a] = val
    # x-y plane: v (1, 7), θz (5, 11)
    phi = 12.0 * e * iz / (kappa * g * area * ll * ll)
    c = e * iz / ((1.0 + phi) * ll**3)
    block = c * np.array(
        [
            [12.0, 6.0 * ll, -12.0, 6.0 * ll],
            [6.0 * ll, (4.0 + phi) * ll * ll, -6.0 * ll, (2.0 - phi) * ll * ll],
            [-12.0, -6.0 * ll, 12.0, -6.0 * ll],
            [6.0 * ll, (2.0 - phi) * ll * ll, -6.0 * ll, (4.0 + phi) * ll * ll],
        ]
    )
    idx = [1, 5, 7, 11]
    k[np.ix_(idx, idx)] += block
    # x-z plane: w (2, 8), θy (4, 10); the rotation sign is opposite (θy = −dw/dx)
    phi = 12.0 * e * iy / (kappa * g * area * ll * ll)
    c = e * iy / ((1.0 + phi) * ll**3)
    block = c * np.array(
        [
            [12.0, -6.0 * ll, -12.0, -6.0 * ll],
            [-6.0 * ll, (4.0 + phi) * ll * ll, 6.0 * ll, (2.0 - phi) * ll * ll],
            [-12.0, 6.0 * ll, 12.0, 6.0 * ll],
            [-6.0 * ll, (2.0 - phi) * ll * ll, 6.0 * ll, (4.0 + phi) * ll * ll],
        ]
    )
    idx = [2, 4, 8, 10]
    k[np.ix_(idx, idx)] += block
    return k


def _element_global(k_local: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Rotate a local 12×12 stiffness into the global frame; ``axes`` rows are local x, y, z."""
    t = np.zeros((12, 12))
    for i in range(4):
        t[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = axes
    return t.T @ k_local @ t


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


@dataclass(frozen=True)
class SegmentFE:
    """One segment: three (or more) identical leaves between two rigid disks, a central joint."""

    leaf: LeafSection
    free_length: float
    leaf_radius: float
    leaf_angles_deg: tuple[float, ...] = (0.0, 120.0, 240.0)
    joint: str = "ball"
    elements_per_leaf: int = 8

    def __post_init__(self) -> None:
        require_positive("free_length", self.free_length)
        require_range("leaf_radius", self.leaf_radius, 0.0, 1.0, low_inclusive=True)
        require_int("elements_per_leaf", self.elements_per_leaf, 1, 1000)
        if self.joint not in ("ball", "universal"):
            raise ValueError(
                f"joint: must be 'ball' or 'universal' (got {self.joint!r})"
            )

    def assemble(self) -> tuple[np.ndarray, int]:
        """Global stiffness over (all leaf nodes × 6) + reference node (6), and the reference's first DoF."""
        n_el = self.elements_per_leaf
        n_nodes = len(self.leaf_angles_deg) * (n_el + 1)
        ref = 6 * n_nodes
        size = ref + 6
        k = np.zeros((size, size))
        sec = self.leaf
        h = self.free_length / n_el
        k_local = frame_element_stiffness(
            h, sec.youngs_modulus, sec.shear_modulus, sec.area,
            iy=sec.i_radial_axis, iz=sec.i_tangential_axis, j=sec.torsion_constant, kappa=sec.shear_coefficient,
        )  # fmt: skip
        for leaf_i, angle in enumerate(np.radians(self.leaf_angles_deg)):
            radial = np.array([math.cos(angle), math.sin(angle), 0.0])
            tangential = np.array([-math.sin(angle), math.cos(angle), 0.0])
            axes = np.vstack(
                [np.array([0.0, 0.0, 1.0]), radial, tangential]
            )  # local x, y, z
            k_global = _element_global(k_local, axes)
            for e in range(n_el):
                first = 6 * (leaf_i * (n_el + 1) + e)
                dofs = np.arange(first, first + 12)
                k[np.ix_(dofs, dofs)] += k_global
        return k, ref

    def node_positions(self) -> np.ndarray:
        """(n_nodes, 3) leaf node positions, joint centre at the origin, lower disk face at z = −g/2."""
        out = []
        zs = np.linspace(
            -self.free_length / 2.0, self.free_length / 2.0, self.elements_per_leaf + 1
        )
        for angle in np.radians(self.leaf_angles_deg):
            xy = self.leaf_radius * np.array([math.cos(angle), math.sin(angle)])
            out.extend([(xy[0], xy[1], z) for z in zs])
        return np.array(out)

    def stiffness(self) -> np.ndarray:
        """Rotational stiffness about the joint centre: 3×3 (ball) or 2×2 (universal, x and y)."""
        k, ref = self.assemble()
        n_el = self.elements_per_leaf
        positions = self.node_positions()
        n_nodes = len(positions)
        free_rot = 3 if self.joint == "ball" else 2
        # reduced DoFs: interior nodes' 6 each, then the reference node's free rotations
        interior = [i for i in range(n_nodes) if i % (n_el + 1) not in (0, n_el)]
        n_red = 6 * len(interior) + free_rot
        t = np.zeros((k.shape[0], n_red))
        for col, node in enumerate(interior):
            t[6 * node : 6 * node + 6, 6 * col : 6 * col + 6] = np.eye(6)
        rot_cols = slice(6 * len(interior), n_red)
        # reference node: translations fixed by the joint, rotations (x, y[, z]) free
        t[ref + 3 : ref + 3 + free_rot, rot_cols] = np.eye(free_rot)
        # upper leaf ends follow the rigid upper disk: u = θ × p, rotation = θ
        for node in range(n_el, n_nodes, n_el + 1):
            rigid = np.zeros((6, 3))
            rigid[:3] = -_skew(positions[node])  # θ × p = −[p]× θ
            rigid[3:] = np.eye(3)
            t[6 * node : 6 * node + 6, rot_cols] = rigid[:, :free_rot]
        # lower leaf ends: clamped (columns stay zero)
        k_red = t.T @ k @ t
        factor = cho_factor(k_red)
        loads = np.zeros((n_red, free_rot))
        loads[6 * len(interior) :, :] = np.eye(free_rot)
        compliance = cho_solve(factor, loads)[6 * len(interior) :, :]
        return np.linalg.inv(compliance)



def section_fe_stiffness(geometry: ArmGeometry, section: SectionGeometry) -> np.ndarray:
    """The FE stiffness matrix of one physical segment of ``section``, built from its leaf fields
    (width, thickness, free length, radius, angles), the material and the central joint only."""
    leaf = LeafSection(section.hinge_width, section.hinge_thickness, geometry.material.youngs_modulus, geometry.material.poisson_ratio)
    return SegmentFE(
        leaf,
        free_length=section.leaf_length(geometry.disk_thickness),
        leaf_radius=section.leaf_radius,
        leaf_angles_deg=section.leaf_angles_deg,
        joint=geometry.central_joint,
    ).stiffness()

def cantilever_chain(
    length: float, section: LeafSection, n_elements: int, tip_load: np.ndarray
) -> np.ndarray:
    """Tip displacement/rotation (6,) of a straight cantilever along z under a tip load (Fx, Fy, Fz, Mx, My, Mz).

    The same elements as the segment model, for the textbook checks (PL³/3EI, TL/GJ).
    """
    h = length / n_elements
    k_local = frame_element_stiffness(
        h, section.youngs_modulus, section.shear_modulus, section.area,
        iy=section.i_radial_axis, iz=section.i_tangential_axis, j=section.torsion_constant, kappa=section.shear_coefficient,
    )  # fmt: skip
    axes = np.vstack(
        [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    )  # local y = global x (radial)
    k_global = _element_global(k_local, axes)
    size = 6 * (n_elements + 1)
    k = np.zeros((size, size))
    for e in range(n_elements):
        dofs = np.arange(6 * e, 6 * e + 12)
        k[np.ix_(dofs, dofs)] += k_global
    free = np.arange(6, size)
    load = np.zeros(size)
    load[-6:] = tip_load
    u = np.zeros(size)
    u[free] = np.linalg.solve(k[np.ix_(free, free)], load[free])
    return u[-6:]
