"""Segment stiffness (bend about x and y, twist about z) and its scaling to any model segment count.

Flexure backbone (``ArmGeometry.backbone = "flexure"``; derivation in docs/model.md,
"Segment stiffness"): one segment joins two rigid disks by a central joint at mid-gap
and three straight leaves of width w (tangential), thickness t (radial) and free length
g, clamped in both disks, their centroids at radius r and angles α_i. A small rotation
ω of the upper disk about the joint centre moves leaf i's upper end by ω × (p_i + g/2·e_z)
and turns it by ω, so each leaf is a clamped–clamped beam loaded at one end:

* bending about an in-plane axis: the leaf's end slides g/2·θ while it turns θ — a
  constant-curvature arc with zero shear force, energy ½·E·I_n/g·θ² (I_n: the leaf's
  second moment about the bending axis: I_hard = t w³/12 about its radial axis,
  I_easy = w t³/12 about its tangential axis);
* the same rotation lifts the leaf's end by (ω × p_i)_z, so a leaf off the axis
  stretches: energy ½·(EA/g)·(ω × p_i)_z², A = w·t — the term that dominates once r
  exceeds a few millimetres;
* twist ω_z turns each leaf end about its own axis (St Venant torsion of a thin strip,
  GJ/g with J = w t³/3·(1 − 0.63 t/w)) and slides it r·ω_z tangentially without turning
  it (clamped–guided beam bent about its hard axis, shear included because w/g is not
  small: k = 12EI_hard/g³/(1 + Φ), Φ = 12EI_hard/(κGAg²), κ = 5/6).

Summing the three leaves gives a 3×3 segment stiffness matrix about the joint centre;
three leaves 120° apart make it diagonal and isotropic in bending. A universal central
joint blocks twist (infinite twist stiffness). The central joint carries every force.

Rod backbone (``backbone = "rod"``): joint i stands for a rod piece of one pitch p, so
K_bend = EI/p and K_twist = GJ/p with I = πr⁴/4 and J = πr⁴/2.

A section's equivalent continuous rigidity is K_seg·pitch (M = EI·κ with κ = (θ/n)/pitch),
and a model with n_model joints per section uses k_joint = n_model·EI_sec/L, so the
section bends the same whatever n_model is.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import ArmGeometry, SectionGeometry

SHEAR_COEFFICIENT_RECT = (
    5.0 / 6.0
)  # Timoshenko shear coefficient of a rectangular section


def strip_torsion_constant(width: float, thickness: float) -> float:
    """St Venant torsion constant of a thin rectangular strip, J ≈ b t³/3·(1 − 0.63 t/b) (Roark)."""
    b, t = max(width, thickness), min(width, thickness)
    return b * t**3 / 3.0 * (1.0 - 0.63 * t / b)


def leaf_lever_arms(section: SectionGeometry) -> np.ndarray:
    """(3, 2) in-plane leaf centroid positions (x, y) in the disk frame."""
    a = section.leaf_angles
    return section.leaf_radius * np.column_stack([np.cos(a), np.sin(a)])


def flexure_segment_stiffness_matrix(
    geometry: ArmGeometry, section: SectionGeometry
) -> np.ndarray:
    """3×3 stiffness (N·m/rad) of one flexure segment about its joint centre, axes (x, y, z) of the disk.

    The twist entry is ``inf`` for a universal central joint.
    """
    mat = geometry.material
    e, shear = mat.youngs_modulus, mat.shear_modulus
    w, t = section.hinge_width, section.hinge_thickness
    g = section.leaf_length(geometry.disk_thickness)
    area = w * t
    i_hard, i_easy = t * w**3 / 12.0, w * t**3 / 12.0
    phi = 12.0 * e * i_hard / (SHEAR_COEFFICIENT_RECT * shear * area * g * g)
    k_slide = (
        12.0 * e * i_hard / g**3 / (1.0 + phi)
    )  # clamped-guided, hard axis, with shear
    gj = shear * strip_torsion_constant(w, t)
    k = np.zeros((3, 3))
    for (x, y), alpha in zip(leaf_lever_arms(section), section.leaf_angles):
        er = np.array([math.cos(alpha), math.sin(alpha)])
        et = np.array([-math.sin(alpha), math.cos(alpha)])
        # bending about in-plane axes: E/g·(I_hard er⊗er + I_easy et⊗et)
        k[:2, :2] += e / g * (i_hard * np.outer(er, er) + i_easy * np.outer(et, et))
        # stretching: lift (ω × p)_z = ωx·y − ωy·x
        lever = np.array([y, -x, 0.0])
        k += e * area / g * np.outer(lever, lever)
        # twist: own torsion + tangential slide r·ωz
        k[2, 2] += gj / g + k_slide * (x * x + y * y)
    if geometry.central_joint == "universal":
        k[2, 2] = math.inf
    return k


def segment_stiffness(
    geometry: ArmGeometry, section: SectionGeometry
) -> tuple[float, float, float]:
    """(K_x, K_y, K_twist) in N·m/rad of one physical segment (the diagonal the model's joints get).

    Off-diagonal terms (zero for leaves 120° apart) are not represented by the joints.
    """
    if geometry.backbone == "rod":
        rod = geometry.rod
        p = section.pitch
        ei, gj = (
            rod.youngs_modulus * rod.second_moment,
            rod.shear_modulus * rod.polar_moment,
        )
        return ei / p, ei / p, gj / p
    k = flexure_segment_stiffness_matrix(geometry, section)
    return float(k[0, 0]), float(k[1, 1]), float(k[2, 2])


def segment_bending_stiffness(geometry: ArmGeometry, section: SectionGeometry) -> float:
    """K_seg (N·m/rad): one physical segment's bending stiffness, mean of the x and y axes."""
    kx, ky, _ = segment_stiffness(geometry, section)
    return 0.5 * (kx + ky)


def section_bending_rigidity(geometry: ArmGeometry, section: SectionGeometry) -> float:
    """EI_sec (N·m²): the section's equivalent continuous bending rigidity."""
    return segment_bending_stiffness(geometry, section) * section.pitch


def joint_stiffnesses(
    geometry: ArmGeometry, section_index: int, n_model: int, scale: float = 1.0
) -> tuple[float, float, float]:
    """Per-joint (k_x, k_y, k_twist) for a model with ``n_model`` joints in the section.

    k = scale·n_model·K_seg·pitch/L per axis: the section's rigidities do not depend on
    n_model. The twist value is ``inf`` for a universal central joint.
    """
    section = geometry.sections[section_index]
    factor = scale * section.stiffness_scale * n_model * section.pitch / section.length
    kx, ky, kz = segment_stiffness(geometry, section)
    return factor * kx, factor * ky, factor * kz


def joint_stiffness(
    geometry: ArmGeometry, section_index: int, n_model: int, scale: float = 1.0
) -> float:
    """Per-joint bending stiffness k = n_model·EI_sec/L (mean of x and y) for a model with ``n_model`` joints."""
    kx, ky, _ = joint_stiffnesses(geometry, section_index, n_model, scale)
    return 0.5 * (kx + ky)


def leaf_peak_strain(geometry: ArmGeometry, section: SectionGeometry, bend: float | None = None) -> float:
    """Largest axial strain in a leaf when the section is bent by ``bend`` (default: its max bend).

    Plane sections of a leaf whose ends turn with the disks about the joint centre: a
    fibre at in-plane position P strains by (θ_seg/g)·(P·m), m ⟂ the bending axis, so
    the peak is θ_seg/g times the farthest leaf corner's distance from the axis.
    """
    theta = (section.max_bend if bend is None else bend) / section.n_segments
    g = section.leaf_length(geometry.disk_thickness)
    reach = math.hypot(section.leaf_radius + section.hinge_thickness / 2.0, section.hinge_width / 2.0)
    return theta * reach / g


def strain_limited_leaf_radius(geometry: ArmGeometry, section: SectionGeometry) -> float:
    """The largest leaf radius whose peak strain at the section's max bend stays within the material's limit.

    Zero when even leaves on the axis exceed it (their own bending alone is too much).
    """
    theta = section.max_bend / section.n_segments
    g = section.leaf_length(geometry.disk_thickness)
    reach = geometry.material.elastic_strain_limit * g / theta
    half_w, half_t = section.hinge_width / 2.0, section.hinge_thickness / 2.0
    if reach <= math.hypot(half_t, half_w):
        return 0.0
    return math.sqrt(reach * reach - half_w * half_w) - half_t


def bend_tension(geometry: ArmGeometry, section_index: int, bend: float | None = None, scale: float = 1.0) -> float:
    """Quasi-static cable tension (N) that holds a section at ``bend`` (default max): K_seg·θ_seg = T·lever.

    One cable in the bending plane. Its lever about each joint is the distance from the joint
    to the straight cable piece between the holes of the two disks (SPEC §2's closed-loop
    vector): r·cos(θ_seg/2) + (p/2)·sin(θ_seg/2), 5 % more than r at 9° per segment. A bend
    30° off a cable needs about 1/cos 30° more. Gravity, pretension and the distal cables'
    loads on this section are not included.
    """
    section = geometry.sections[section_index]
    theta = (section.max_bend if bend is None else bend) / section.n_segments
    r, half_pitch = section.hole_radius(geometry.cable_hole_radius), section.pitch / 2.0
    lever = r * math.cos(theta / 2.0) + half_pitch * math.sin(theta / 2.0)
    return scale * segment_bending_stiffness(geometry, section) * theta / lever


def strain_limited_geometry(geometry: ArmGeometry, resolution: float = 1e-4) -> ArmGeometry:
    """``geometry`` with every section's leaves at its strain-limited radius, rounded down to ``resolution``.

    For the defaults: 2.9 / 2.3 / 1.8 mm (proximal, middle, distal).
    """
    import dataclasses

    sections = tuple(
        dataclasses.replace(
            s, leaf_radius=round(math.floor(strain_limited_leaf_radius(geometry, s) / resolution + 1e-9) * resolution, 12)
        )
        for s in geometry.sections
    )
    return dataclasses.replace(geometry, sections=sections)
