"""Flexure-hinge stiffness of a segment, and its scaling to any model segment count.

Each physical segment joins two disks by a central ball joint and three identical leaf
hinges (width w, thickness t) at 120°, free length g = pitch − disk thickness between
the disks. Assumptions:

* each leaf is an Euler–Bernoulli strip in pure bending about the ball joint (the ball
  joint carries the axial and shear loads), so its rotational stiffness is E·I/g;
* a leaf's cross-section is w (tangential) × t (radial); bending about an axis at angle
  ψ to its tangential axis uses E(I_easy cos²ψ + I_hard sin²ψ)/g with
  I_easy = w t³/12 and I_hard = t w³/12;
* three leaves at 120°: Σcos²ψ = Σsin²ψ = 3/2 for every ψ, so the segment is isotropic
  in bending:

      K_seg = (3/2)·E·(I_easy + I_hard)/g = E·w·t·(w² + t²) / (8 g)

The section's equivalent bending stiffness is EI_sec = K_seg·pitch (M = EI·κ with
κ = (θ/n)/pitch), and a model with n_model joints per section uses
k_joint = n_model·EI_sec/L, so the section bends the same whatever n_model is.
MuJoCo's ball-joint spring is isotropic: the twist stiffness equals the bending one
(the leaves' real twist stiffness is higher; the hinge-pair option locks twist).
"""

from __future__ import annotations

from ..geometry import ArmGeometry, SectionGeometry


def segment_bending_stiffness(geometry: ArmGeometry, section: SectionGeometry) -> float:
    """K_seg (N·m/rad) of one physical segment of ``section``."""
    w, t = section.hinge_width, section.hinge_thickness
    g = section.pitch - geometry.disk_thickness
    return geometry.material.youngs_modulus * w * t * (w * w + t * t) / (8.0 * g)


def section_bending_rigidity(geometry: ArmGeometry, section: SectionGeometry) -> float:
    """EI_sec (N·m²): the section's equivalent continuous bending rigidity."""
    return segment_bending_stiffness(geometry, section) * section.pitch


def joint_stiffness(geometry: ArmGeometry, section_index: int, n_model: int, scale: float = 1.0) -> float:
    """Per-joint stiffness k = n_model·EI_sec/L for a model with ``n_model`` joints."""
    section = geometry.sections[section_index]
    return scale * n_model * section_bending_rigidity(geometry, section) / section.length
