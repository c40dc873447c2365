"""The arm's geometry: the one place where section sizes, cable holes and tools live.

Both the kinematic model (``kinematics``) and the MuJoCo model builders read these
dataclasses, so the simulated robot and the planner can never disagree about a size.
Units: metres, kilograms, pascals; angles carry a ``_deg`` suffix and are in degrees.
Defaults follow SPEC §1 (paper Table 1); values the paper does not give are marked
*assumed* and are configurable.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from .configio import (
    ConfigError,
    config_from_file,
    from_dict,
    require_int,
    require_positive,
    require_range,
    save_toml,
    to_dict,
)


@dataclass(frozen=True)
class SectionGeometry:
    """One 2-DoF section: ``n_segments`` identical segments bent by three cables."""

    length: float
    disk_diameter: float
    hinge_width: float
    hinge_thickness: float
    n_segments: int = 10  # assumed
    cable_angles_deg: tuple[float, float, float] = (0.0, 120.0, 240.0)  # assumed
    max_bend_deg: float = 90.0
    # Flexure leaves (docs/model.md "Segment stiffness"): centroid distance from the
    # joint axis, angular positions in the disk frame, and free length between the disk
    # faces (0 = the whole gap, pitch − disk thickness). Hinge width is tangential,
    # hinge thickness radial.
    leaf_radius: float = 0.0
    leaf_angles_deg: tuple[float, float, float] = (0.0, 120.0, 240.0)
    leaf_free_length: float = 0.0
    # Per-section calibration (identified from recordings, docs/sysid.md; the defaults change
    # nothing): the section's joint springs x stiffness_scale (on top of model.stiffness_scale),
    # its three cables' stiffness x cable_gain_scale, its holes at cable_hole_radius from the
    # axis (0: the arm's), its cable pattern turned by cable_angle_offset_deg about the axis,
    # and extra_pretension N added to control.pretension in its cables (the replay's calibration).
    stiffness_scale: float = 1.0
    cable_gain_scale: float = 1.0
    cable_hole_radius: float = 0.0
    cable_angle_offset_deg: float = 0.0
    extra_pretension: float = 0.0

    def __post_init__(self) -> None:
        require_positive("length", self.length)
        require_range("stiffness_scale", self.stiffness_scale, 0.0, 1e4)
        require_range("cable_gain_scale", self.cable_gain_scale, 0.0, 1e4)
        require_range("cable_hole_radius", self.cable_hole_radius, 0.0, 1.0, low_inclusive=True)
        require_range("cable_angle_offset_deg", self.cable_angle_offset_deg, -180.0, 180.0, low_inclusive=True)
        require_range("extra_pretension", self.extra_pretension, 0.0, 1000.0, low_inclusive=True)
        require_positive("disk_diameter", self.disk_diameter)
        require_positive("hinge_width", self.hinge_width)
        require_positive("hinge_thickness", self.hinge_thickness)
        require_int("n_segments", self.n_segments, 1, 200)
        require_range("leaf_radius", self.leaf_radius, 0.0, 1.0, low_inclusive=True)
        require_range("leaf_free_length", self.leaf_free_length, 0.0, 1.0, low_inclusive=True)
        if len(self.leaf_angles_deg) != 3:
            raise ConfigError("leaf_angles_deg", f"must have exactly 3 entries (got {len(self.leaf_angles_deg)})")
        for i, angle in enumerate(self.leaf_angles_deg):
            require_range(f"leaf_angles_deg[{i}]", angle, -360.0, 360.0, low_inclusive=True)
        if len(self.cable_angles_deg) != 3:
            raise ConfigError("cable_angles_deg", f"must have exactly 3 entries (got {len(self.cable_angles_deg)})")
        for i, angle in enumerate(self.cable_angles_deg):
            require_range(f"cable_angles_deg[{i}]", angle, -360.0, 360.0, low_inclusive=True)
        wrapped = sorted(a % 360.0 for a in self.cable_angles_deg)
        gaps = np.diff(wrapped + [wrapped[0] + 360.0])
        if gaps.min() < 10.0:
            raise ConfigError("cable_angles_deg", f"cable holes must be at least 10 deg apart (got {self.cable_angles_deg})")
        require_range("max_bend_deg", self.max_bend_deg, 0.0, 180.0)

    @property
    def pitch(self) -> float:
        """Distance between consecutive disk centres."""
        return self.length / self.n_segments

    @property
    def max_bend(self) -> float:
        """Largest bending angle of the section, radians."""
        return math.radians(self.max_bend_deg)

    @property
    def cable_angles(self) -> np.ndarray:
        """The holes' angles about the axis (rad), calibration offset included."""
        return np.radians(np.asarray(self.cable_angles_deg, dtype=float) + self.cable_angle_offset_deg)

    def hole_radius(self, arm_radius: float) -> float:
        """The section's hole radius (m): its own when set, else the arm's."""
        return self.cable_hole_radius if self.cable_hole_radius > 0.0 else arm_radius

    @property
    def leaf_angles(self) -> np.ndarray:
        return np.radians(np.asarray(self.leaf_angles_deg, dtype=float))

    def leaf_length(self, disk_thickness: float) -> float:
        """Free length g of each leaf between the disks (the gap unless set shorter)."""
        return self.leaf_free_length if self.leaf_free_length > 0.0 else self.pitch - disk_thickness

    def check_leaves(self, disk_thickness: float) -> None:
        """Raise unless the three leaves fit inside the disk and inside the gap between disks."""
        gap = self.pitch - disk_thickness
        if self.leaf_free_length > gap:
            raise ConfigError(
                "leaf_free_length",
                f"must satisfy 0 <= leaf_free_length <= pitch - disk_thickness = {gap:g} (got {self.leaf_free_length:g})",
            )
        reach = math.hypot(self.leaf_radius + self.hinge_thickness / 2.0, self.hinge_width / 2.0)
        if reach >= self.disk_diameter / 2.0:
            raise ConfigError(
                "leaf_radius",
                f"leaves reach {reach:g} m from the axis (leaf_radius, hinge_width, hinge_thickness); "
                f"must stay inside the disk radius {self.disk_diameter / 2:g}",
            )


@dataclass(frozen=True)
class RodBackbone:
    """A central elastic rod as every segment's spring (``ArmGeometry.backbone = "rod"``).

    Defaults: superelastic nitinol. E = 50 GPa: NiTi wire datasheets give 41–75 GPa
    for the austenite loading modulus and 28–41 GPa for martensite; 50 GPa is the value
    the OpenCR-MuJoCo FTDCR model uses for its nitinol rod. ν = 0.3 (metal, typical),
    density 6450 kg/m³ (NiTi datasheet). Radius 1 mm (*assumed*): a rod's EI = Eπr⁴/4
    then has the order of the flexure segments' EI_sec, and its surface strain r·κ at
    90° over the shortest section (150 mm) is 1.05 %, well inside NiTi's ~6 %
    recoverable strain.
    """

    radius: float = 1.0e-3
    youngs_modulus: float = 50.0e9
    poisson_ratio: float = 0.3
    density: float = 6450.0

    def __post_init__(self) -> None:
        require_range("radius", self.radius, 0.0, 0.1)
        require_range("youngs_modulus", self.youngs_modulus, 0.0, 1e13)
        require_range("poisson_ratio", self.poisson_ratio, -1.0, 0.5, high_inclusive=False)
        require_range("density", self.density, 0.0, 1e5, low_inclusive=True)

    @property
    def shear_modulus(self) -> float:
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def second_moment(self) -> float:
        """I = πr⁴/4 (bending, either axis)."""
        return math.pi * self.radius**4 / 4.0

    @property
    def polar_moment(self) -> float:
        """J = πr⁴/2 (torsion of a solid circular rod)."""
        return math.pi * self.radius**4 / 2.0


@dataclass(frozen=True)
class Material:
    """Flexure-leaf (and disk) material: a printed engineering polymer (*assumed*, docs/model.md).

    E = 2.0 GPa, ν = 0.38, ρ = 1250 kg/m³: PETG-class printed polymer (datasheet tensile
    modulus 2.0–2.1 GPa, ν 0.38–0.40, density 1.23–1.27 g/cm³). ``elastic_strain_limit``
    4 %: such polymers yield near 4–6 % strain; the default leaves sit as far off the
    joint as this allows at each section's full bend (``model.stiffness.strain_limited_leaf_radius``).
    """

    youngs_modulus: float = 2.0e9
    poisson_ratio: float = 0.38
    density: float = 1250.0
    elastic_strain_limit: float = 0.04

    def __post_init__(self) -> None:
        require_range("youngs_modulus", self.youngs_modulus, 0.0, 1e13)
        require_range("poisson_ratio", self.poisson_ratio, -1.0, 0.5, high_inclusive=False)
        require_range("density", self.density, 0.0, 1e5)
        require_range("elastic_strain_limit", self.elastic_strain_limit, 0.0, 1.0)

    @property
    def shear_modulus(self) -> float:
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))


@dataclass(frozen=True)
class ToolGeometry:
    """Tool lengths beyond the last disk centre along the tip's z (*assumed*)."""

    grinder_length: float = 0.060
    gripper_length: float = 0.070
    # Where a recording's measured point (a motion-capture marker) sits relative to the tool
    # centre point, in the tool frame (m); replay/identify compare the model at that point.
    marker_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        require_range("grinder_length", self.grinder_length, 0.0, 1.0, low_inclusive=True)
        require_range("gripper_length", self.gripper_length, 0.0, 1.0, low_inclusive=True)
        if len(self.marker_offset) != 3:
            raise ConfigError("marker_offset", f"must have 3 entries x, y, z (got {len(self.marker_offset)})")
        for i, v in enumerate(self.marker_offset):
            require_range(f"marker_offset[{i}]", v, -1.0, 1.0, low_inclusive=True)

    def length(self, tool: str) -> float:
        if tool == "grinder":
            return self.grinder_length
        if tool == "gripper":
            return self.gripper_length
        if tool == "none":
            return 0.0
        raise ConfigError("tool", f"must be one of 'grinder', 'gripper', 'none' (got {tool!r})")


def _default_sections() -> tuple[SectionGeometry, ...]:
    # Base -> tip; the paper numbers sections from the tip (its Section 3 is our index 0).
    # Leaves at the strain-limited radius (docs/model.md: 2.9/2.3/1.8 mm, x3.3-3.7 stiffer
    # than leaves bent about the joint, ``model.stiffness.strain_limited_geometry``); the
    # closed loop holds on this plant with the elastic cables (docs/plant.md).
    return (
        SectionGeometry(0.210, 0.046, 0.006, 0.001, cable_angles_deg=(0.0, 120.0, 240.0), leaf_radius=0.0029),
        SectionGeometry(0.180, 0.043, 0.005, 0.001, cable_angles_deg=(40.0, 160.0, 280.0), leaf_radius=0.0023),
        SectionGeometry(0.150, 0.040, 0.004, 0.001, cable_angles_deg=(80.0, 200.0, 320.0), leaf_radius=0.0018),
    )


@dataclass(frozen=True)
class ArmGeometry:
    """A whole arm, base to tip. ``q = (θ0, φ0, θ1, φ1, θ2, φ2)`` follows the section order."""

    sections: tuple[SectionGeometry, ...] = field(default_factory=_default_sections)
    cable_hole_radius: float = 0.015  # assumed
    disk_thickness: float = 0.003  # assumed
    spool_radius: float = 0.010  # assumed: motor spool radius, converts Δl to motor angle
    material: Material = field(default_factory=Material)
    tools: ToolGeometry = field(default_factory=ToolGeometry)
    # The segments' spring: "flexure" (three leaves per segment, Table 1) or "rod" (one
    # central elastic rod through all disks, ``rod``; the leaf fields are then unused).
    backbone: Literal["flexure", "rod"] = "flexure"
    rod: RodBackbone = field(default_factory=RodBackbone)
    # The central joint of a flexure segment: "ball" (3 rotations free: the leaves alone
    # resist twist) or "universal" (twist blocked by the joint). Default universal: the
    # paper's prototype photo shows a "2-DoF universal joint" (Fig. 13d) in its "2-DoF
    # segments"; its text says "ball joint". The scenario's hinge_pair model matches it.
    central_joint: Literal["ball", "universal"] = "universal"
    # The nonlinear leaf model's stress-free bow, as a fraction of the leaf's free length
    # (plant/leaf_rod.py): a numerical seed that lets a compressed leaf leave the straight
    # branch of its buckling problem (a perfectly straight rod has no direction to buckle in);
    # small enough not to change the leaf's stiffness. Not a measured imperfection.
    leaf_bow_fraction: float = 5e-4

    def __post_init__(self) -> None:
        if not isinstance(self.sections, tuple) or not 1 <= len(self.sections) <= 10:
            raise ConfigError("sections", "must be a list of 1 to 10 sections")
        for i, section in enumerate(self.sections):
            if not isinstance(section, SectionGeometry):
                raise ConfigError(f"sections[{i}]", "must be a section table")
        if self.backbone not in ("flexure", "rod"):
            raise ConfigError("backbone", f"must be 'flexure' or 'rod' (got {self.backbone!r})")
        if self.central_joint not in ("ball", "universal"):
            raise ConfigError("central_joint", f"must be 'ball' or 'universal' (got {self.central_joint!r})")
        require_range("disk_thickness", self.disk_thickness, 0.0, 0.1)
        require_range("leaf_bow_fraction", self.leaf_bow_fraction, 0.0, 0.1, low_inclusive=True)
        require_range("spool_radius", self.spool_radius, 0.0, 1.0)
        smallest = min(s.disk_diameter for s in self.sections) / 2.0
        require_range("cable_hole_radius", self.cable_hole_radius, 0.0, 1.0)
        if self.cable_hole_radius >= smallest:
            raise ConfigError(
                "cable_hole_radius",
                f"must satisfy 0 < cable_hole_radius < smallest disk radius {smallest:g} m "
                f"(holes must lie inside every disk; got {self.cable_hole_radius:g})",
            )
        for i, section in enumerate(self.sections):
            if section.cable_hole_radius >= smallest:
                raise ConfigError(f"sections[{i}].cable_hole_radius",
                                  f"must be < smallest disk radius {smallest:g} m (got {section.cable_hole_radius:g})")
        for i, section in enumerate(self.sections):
            if self.disk_thickness >= section.pitch:
                raise ConfigError(
                    "disk_thickness",
                    f"must be smaller than every segment pitch; section {i} has pitch "
                    f"{section.pitch:g} m (got {self.disk_thickness:g})",
                )
            if self.backbone == "flexure":
                try:
                    section.check_leaves(self.disk_thickness)
                except ConfigError as exc:
                    raise exc.under(f"sections[{i}]") from None
            elif self.rod.radius >= section.disk_diameter / 2.0:
                raise ConfigError("rod.radius", f"must be smaller than every disk radius (section {i}: {section.disk_diameter / 2:g} m)")

    # -------------------------------------------------------------- construction
    @classmethod
    def default(cls) -> ArmGeometry:
        """SPEC §1's arm (paper Table 1 plus the documented assumptions)."""
        return cls()

    @classmethod
    def from_dict(cls, data: dict) -> ArmGeometry:
        return from_dict(cls, data)

    @classmethod
    def from_toml(cls, path: str | os.PathLike[str]) -> ArmGeometry:
        """Load from TOML; errors name the file and the field."""
        return config_from_file(path, lambda data: from_dict(cls, data))

    def to_dict(self) -> dict:
        return to_dict(self)

    def save_toml(self, path: str | os.PathLike[str]) -> None:
        save_toml(self, path)

    # -------------------------------------------------------------- derived facts
    @property
    def n_sections(self) -> int:
        return len(self.sections)

    @property
    def n_cables(self) -> int:
        return 3 * self.n_sections

    @property
    def length(self) -> float:
        return sum(s.length for s in self.sections)

    @property
    def n_disks(self) -> int:
        """Disks including the base plate (disk 0)."""
        return 1 + sum(s.n_segments for s in self.sections)

    @property
    def max_bend(self) -> np.ndarray:
        return np.array([s.max_bend for s in self.sections])

    def cable_holes(self) -> np.ndarray:
        """(n_cables, 3) hole positions in a disk frame, section-major, base→tip."""
        angles = np.concatenate([s.cable_angles for s in self.sections])
        r = np.repeat([s.hole_radius(self.cable_hole_radius) for s in self.sections], 3)
        return np.stack([r * np.cos(angles), r * np.sin(angles), np.zeros_like(angles)], axis=1)

    def cable_names(self, arm: str) -> list[str]:
        """SPEC §6 tendon names, in ``cable_lengths`` order."""
        from .model.names import arm_cable_names  # the builders' naming (model/names.py)

        return arm_cable_names(arm, self.n_sections)
