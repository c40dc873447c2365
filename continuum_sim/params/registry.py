"""The parameter registry: every physical parameter of the plant, with what is known about it.

The registry holds *metadata* only (unit, status, source, plausible range); the value of a
parameter always comes from a resolved ``ScenarioConfig`` (the shipped defaults in
``continuum_sim/data/scenario.toml`` or a user's file), so a default cannot drift between
two places. Each entry's ``path`` is the dotted config path a scenario TOML or a sweep spec
uses (``model.cable_friction.mu``).

Status:

* ``measured``: a figure of the prototype (the paper's Table 1);
* ``derived``: computed from other parameters (``source`` says from what);
* ``assumed``: chosen with a stated reason where neither the paper nor a datasheet fixes it;
  every assumed parameter has a plausible ``range`` (``log`` where it spans a decade or more),
  the range the sensitivity studies and the design optimiser sample;
* ``fitted``: identified by an optimiser from data (``source`` says which data and how); a value
  kept after a coarse check against a published result is ``assumed``, with the check in its source.

A few entries are numerical rather than physical (an armature that regularises a light body, the
leaf model's buckling seed); their source says so. A vector field (a MuJoCo ``solref``/``solimp``,
a list of angles) is registered by its elements that matter (``...solref.1``: the damping ratio).
Choices that are not numbers have no entry; where one shapes a parameter (the central joint of a
flexure segment, ``arm.central_joint``), the related entry's source names it.

Low layer: imports only ``configio``; the functions take any config object whose dataclass
tree carries the paths (``ScenarioConfig``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

from ..configio import ConfigError, get_path, migration_note, replace_path

Status = Literal["measured", "derived", "assumed", "fitted"]
STATUSES: tuple[str, ...] = ("measured", "derived", "assumed", "fitted")


@dataclass(frozen=True)
class Parameter:
    """One physical parameter: where it lives in the config and what is known about it."""

    path: str  # dotted scenario-config path (a TOML key path, a sweep-spec grid path)
    name: str  # what it is, in words
    unit: str
    status: Status
    source: str  # paper figure/table, datasheet, literature, or the reasoning; for derived: from what
    range: tuple[float, float] | None = None  # plausible [low, high]; required for assumed
    log: bool = False  # the range spans decades: sample and plot it logarithmically
    # The value the plant uses when the config field holds a sentinel (leaf_free_length 0 = the whole gap).
    effective: Callable[[Any], float] | None = None

    def value(self, config: Any) -> float:
        """The value the plant uses for this parameter in ``config``."""
        if self.effective is not None:
            return float(self.effective(config))
        return float(get_path(config, self.path))

    def in_range(self, value: float, rel_tol: float = 1e-9) -> bool:
        if self.range is None:
            return True
        low, high = self.range
        slack = rel_tol * max(abs(low), abs(high))
        return low - slack <= value <= high + slack

    def range_text(self) -> str:
        if self.range is None:
            return ""
        low, high = self.range
        return f"{low:g} to {high:g}" + (" (log)" if self.log else "")


# ------------------------------------------------------------------------ the entries
SECTION_NAMES = ("proximal", "middle", "distal")
TABLE1 = "paper Table 1 (our base→tip order: its Sections 3, 2, 1)"
# Per-section figures at the defaults: the gap between disks (pitch − disk thickness), m.
_GAPS = (0.018, 0.015, 0.012)
_LEAF_RADII = (0.0029, 0.0023, 0.0018)
_CABLE_ANGLES = (0.0, 40.0, 80.0)  # each section's first cable hole, deg


def _leaf_length(k: int) -> Callable[[Any], float]:
    def effective(config: Any) -> float:
        return float(config.arm.sections[k].leaf_length(config.arm.disk_thickness))

    return effective


def _section_entries() -> list[Parameter]:
    out: list[Parameter] = []
    for k, where in enumerate(SECTION_NAMES):
        p = f"arm.sections.{k}"
        out += [
            Parameter(f"{p}.length", f"{where} section length", "m", "measured", TABLE1),
            Parameter(f"{p}.disk_diameter", f"{where} disk diameter", "m", "measured", TABLE1),
            Parameter(f"{p}.hinge_width", f"{where} flexure leaf width (tangential)", "m", "measured", TABLE1),
            Parameter(f"{p}.hinge_thickness", f"{where} flexure leaf thickness (radial)", "m", "measured", TABLE1),
            Parameter(
                f"{p}.leaf_radius", f"{where} leaf centroid distance from the joint axis", "m", "derived",
                "largest radius whose peak leaf strain at the 90° section bend stays within arm.material.elastic_strain_limit "
                "(model.stiffness.strain_limited_leaf_radius, rounded down to 0.1 mm; docs/model.md); "
                "range: 1 mm off the axis up to 1.3× that radius (a designer accepting more strain)",
                (0.001, round(1.3 * _LEAF_RADII[k], 6)),
            ),
            Parameter(
                f"{p}.n_segments", f"{where} number of segments (disks above the base disk)", "1", "assumed",
                "assumed: 10 per section, the prototype's disk count read from paper Fig. 13; each segment has a "
                "central joint, arm.central_joint = universal (a choice: Fig. 13d shows a 2-DoF universal joint, the text "
                "says ball joint; the scenario's hinge_pair joints model it). Integer: a sampled value is rounded",
                (8.0, 12.0),
            ),
            Parameter(
                f"{p}.cable_angles_deg.0", f"{where} angle of the first cable hole (the other two keep theirs)", "deg", "assumed",
                "three holes 120° apart per section, each section's set turned 40° from the one below so the nine "
                "holes interleave on the disks; range: that hole misplaced by up to 10° "
                f"(arm.sections.{k}.cable_angle_offset_deg turns the whole set)",
                (_CABLE_ANGLES[k] - 10.0, _CABLE_ANGLES[k] + 10.0),
            ),
            Parameter(
                f"{p}.leaf_angles_deg.0", f"{where} angle of the first flexure leaf (the other two keep theirs)", "deg", "assumed",
                "three leaves 120° apart (the symmetric design); the first at 0° fixes the disk frame the cable angles are "
                "given in; the nonlinear flexure model (the default) takes only angles on its 15° grid, so sample it on that "
                "grid or with model.flexure_model = linear",
                (-15.0, 15.0),
            ),
            Parameter(
                f"{p}.leaf_free_length", f"{where} leaf free length between the disk faces", "m", "assumed",
                f"the whole gap pitch − disk thickness ({1e3 * _GAPS[k]:g} mm; config value 0 means the gap); the print's "
                "fillets and clamped roots may leave 3-6 mm free, ×3-6 stiffer (reference/fidelity-notes.md)",
                (0.003, _GAPS[k]), effective=_leaf_length(k),
            ),
        ]
    return out


_ENTRIES: list[Parameter] = [
    *_section_entries(),
    # ------------------------------------------------------------ arm: material, disks, tools
    Parameter("arm.material.youngs_modulus", "flexure material Young's modulus", "Pa", "assumed",
              "PETG-class printed polymer, datasheet tensile modulus 2.0-2.1 GPa; printed parts 1.5-2.5 GPa "
              "(raster orientation, infill)", (1.5e9, 2.5e9)),
    Parameter("arm.material.poisson_ratio", "flexure material Poisson's ratio", "1", "assumed",
              "PETG datasheets 0.38-0.40; printed polymers 0.35-0.42", (0.35, 0.42)),
    Parameter("arm.material.density", "disk and leaf material density", "kg/m³", "assumed",
              "PETG 1.23-1.27 g/cm³; PLA 1.24, nylon 1.14 (printed solid)", (1100.0, 1300.0)),
    Parameter("arm.material.elastic_strain_limit", "flexure elastic strain limit", "1", "assumed",
              "printed PETG-class polymers yield near 4-6 % strain (PETG ~50 MPa at ~2.5 % per "
              "reference/fidelity-notes.md); sets the leaf radius", (0.02, 0.06)),
    Parameter("arm.disk_thickness", "disk thickness", "m", "assumed",
              "assumed default; printable disks 2-5 mm", (0.002, 0.005)),
    Parameter("arm.cable_hole_radius", "cable hole radius on the disks", "m", "assumed",
              "assumed default; must stay inside the 20 mm distal disk radius with wall left", (0.012, 0.017)),
    Parameter("arm.spool_radius", "motor spool radius", "m", "assumed",
              "converts cable travel to motor angle; 5-20 mm spools on 22 mm gear motors", (0.005, 0.02)),
    Parameter("arm.tools.grinder_length", "grinder tool-centre distance beyond the last disk", "m", "assumed",
              "assumed default; paper Fig. 13 shows a short burr holder", (0.04, 0.08)),
    Parameter("arm.tools.gripper_length", "gripper tool-centre distance beyond the last disk", "m", "assumed",
              "assumed default", (0.05, 0.09)),
    # ------------------------------------------------------------ joints, cables, motors
    Parameter("model.joint_damping", "viscous damping per physical joint", "N·m·s/rad", "assumed",
              "hinge + ball-joint friction, scaled like stiffness (model/options.py)", (0.05, 1.0), log=True),
    Parameter("model.joint_armature", "armature (added rotor inertia) of every flexure joint", "kg·m²", "assumed",
              "numerical, not physical: regularises the mass matrix of the light disks (a 40 mm PETG disk's own inertia is "
              "~1e-6 kg·m²); small enough to leave the arm's dynamics alone", (1e-6, 1e-4), log=True),
    Parameter("model.impratio", "friction-to-normal impedance ratio of the contacts (elliptic cones)", "1", "assumed",
              "MuJoCo's knob against frictional creep: a grasp held for seconds (the gripper on the welded sample) slid "
              "~20 mm at 10 (model/arm.py); 100 holds it", (10.0, 300.0), log=True),
    Parameter("arm.leaf_bow_fraction", "stress-free bow of a flexure leaf in the nonlinear leaf model, per free length", "1",
              "assumed", "numerical seed, not a physical constant: it lets a compressed leaf leave the straight branch of its "
              "buckling problem (the first clamped-clamped mode, plant/leaf_rod.py); small enough not to change the "
              "leaf's stiffness. Used by model.flexure_model = nonlinear", (1e-4, 2e-3), log=True),
    Parameter("model.rope_diameter", "cable (wire rope) nominal diameter", "m", "assumed",
              "7x7 stainless rope sized for the pack's pulleys and the 15 mm hole radius (docs/plant.md)", (0.0008, 0.0012)),
    Parameter("model.rope_modulus", "cable effective modulus on the nominal area π d²/4", "Pa", "assumed",
              "checked against the paper's open-loop result (mean path deviation <= 2.5 mm, docs/calibration.md); not fitted: a coarse grid found the result at "
              "66.2-73.2 GPa (EA 5.2-5.75e4 N), at no mu 0-0.25 for <= 47.1 GPa (docs/calibration.md); 73.2 GPa = the "
              "Loos & Co. stretch chart for pre-stretched 7x7 302 SS (G = 1.20e-5), EA 5.75e4 N at d = 1 mm; "
              "metallic fill 0.5-0.6 × wire modulus 60-110 GPa gives 30-66 GPa (reference/fidelity-notes.md). "
              "Range: the plausible band", (3.0e10, 7.5e10)),
    Parameter("model.cable_lead_length", "cable length from the spool to the arm's base plate", "m", "assumed",
              "from the pack's size (0.36 × 0.16 × 0.12 m) plus the routing to the arm base (docs/plant.md)", (0.15, 0.5)),
    Parameter("model.cable_damping", "viscous damping along each cable", "N·s/m", "assumed",
              "motor loop and guides, passive (model/options.py)", (50.0, 800.0), log=True),
    Parameter("model.cable_friction.mu", "Coulomb friction coefficient, cable in the disk holes (capstan)", "1", "assumed",
              "checked against the paper's open-loop result (mean path deviation <= 2.5 mm, docs/calibration.md); not fitted: a coarse grid found the result for "
              "mu 0.1-0.2 at EA 5.75e4 N, 0.15-0.2 at 5.2e4 N; 0.15 = the middle (docs/calibration.md). Steel rope in "
              "printed-polymer holes: dry steel on PETG/nylon 0.1-0.3, lubricated toward 0. Range: the plausible band",
              (0.0, 0.3)),
    Parameter("model.cable_friction.presliding", "Dahl presliding (stick) distance of the hole friction", "m", "assumed",
              "numerical regularisation of stick; rope-on-polymer presliding 0.1-3 mm (model/friction.py)",
              (1e-4, 3e-3), log=True),
    Parameter("model.cable_max_force", "motor force rating at the cable", "N", "assumed",
              "stall torque / spool radius: 2 N·m at 10 mm (22 mm DC motor, ~100:1 planetary); 90° on the proximal "
              "section needs 139 N + pretension (docs/plant.md)", (150.0, 300.0)),
    Parameter("model.motor_max_speed", "motor no-load speed at the cable", "m/s", "assumed",
              "57 rpm at the 10 mm spool (docs/plant.md); the task asks at most 24 mm/s", (0.03, 0.12)),
    Parameter("model.motor_kp", "motor encoder loop proportional gain", "1/s", "assumed",
              "the prototype's encoder loops (gains not given); double pole at 20 rad/s (docs/plant.md)", (20.0, 80.0)),
    Parameter("model.motor_ki", "motor encoder loop integral gain", "1/s²", "derived",
              "ki = kp²/4 (critically damped) from model.motor_kp; range follows kp's", (100.0, 1600.0), log=True),
    Parameter("model.grinder_mass", "grinder tool mass", "kg", "assumed",
              "burr holder and bearings; the spindle motor sits in the pack (flexible shaft)", (0.05, 0.15)),
    Parameter("model.gripper_mass", "gripper tool mass", "kg", "assumed",
              "two printed jaws on slides and a cable pulley", (0.04, 0.1)),
    Parameter("control.pretension", "cable pretension", "N", "assumed",
              "so no cable goes slack when the stiff segments bend (docs/plant.md: 10 N left a quarter of the "
              "records with a slack cable)", (15.0, 50.0)),
    # ------------------------------------------------------------ tools
    Parameter("scene.tools.spindle_speed", "grinder spindle speed command", "rad/s", "assumed",
              "~9500 rpm, a hobby burr grinder's range 5000-20000 rpm", (500.0, 2000.0)),
    Parameter("scene.tools.spindle_max_torque", "grinder spindle torque limit", "N·m", "assumed",
              "a 5 W micro motor at 1000 rad/s (380-size DC motor behind a flexible shaft); a rotary tool "
              "delivers up to ~50 mN·m", (0.005, 0.05), log=True),
    Parameter("scene.tools.spindle_kv", "spindle speed loop proportional gain", "N·m·s/rad", "assumed",
              "bandwidth kv/J ≈ 500 rad/s on the ~2e-6 kg·m² rotor (MuJoCo velocity actuator, implicit; scene_options.py)",
              (5e-4, 4e-3), log=True),
    Parameter("scene.tools.spindle_ki", "spindle speed loop integral gain", "N·m/rad", "assumed",
              "corner ki/kv = 20 rad/s, far below the P loop's bandwidth: removes the cutting load's droop without "
              "overshoot (scene_options.py)", (0.005, 0.08), log=True),
    Parameter("scene.tools.grinder_housing_fraction", "share of the grinder's mass in its housing (the spindle has the rest)",
              "1", "assumed", "bearings and burr holder outweigh the small spinning part; the paper gives no figure", (0.7, 0.95)),
    Parameter("scene.tools.grinder_shaft_fraction", "share of the spindle's mass in its bare shaft (the cutter has the rest)",
              "1", "assumed", "a 4 mm shaft stub against the burr; the paper gives no figure", (0.1, 0.4)),
    Parameter("scene.tools.spindle_armature", "spindle rotor + shaft inertia", "kg·m²", "assumed",
              "a micro motor's rotor is ~1e-6 kg·m² (scene_options.py)", (5e-7, 1e-5), log=True),
    Parameter("scene.tools.gripper_preload", "gripper jaw opening-spring preload", "N", "assumed",
              "must hold the 24 g jaw open in any orientation: 2× its weight (docs/plant.md)", (0.25, 1.0)),
    Parameter("scene.tools.gripper_palm_fraction", "share of the gripper's mass in its palm (each jaw has half the rest)",
              "1", "assumed", "the palm carries the slides and the cable pulley; the paper gives no figure", (0.4, 0.8)),
    Parameter("scene.tools.gripper_pad_fraction", "share of a jaw's mass in its pad (the finger plate has the rest)", "1",
              "assumed", "a 10 mm pad on a 4 mm finger plate; the paper gives no figure", (0.1, 0.4)),
    Parameter("scene.tools.gripper_jaw_armature", "armature of each jaw's slide joint", "kg", "assumed",
              "reflected inertia of the pulley and slide; mostly numerical (regularises the 10 g jaw)", (1e-5, 1e-3), log=True),
    Parameter("scene.tools.gripper_stop_solref.0", "jaw end-stop time constant (MuJoCo solreflimit)", "s", "assumed",
              "a hard stop: MuJoCo's default soft limit let a jaw overrun by 3 mm at full grip force (model/tools.py)",
              (0.005, 0.02)),
    Parameter("scene.tools.gripper_stop_solref.1", "jaw end-stop damping ratio (MuJoCo solreflimit)", "1", "assumed",
              "critically damped, MuJoCo's default", (0.5, 2.0)),
    Parameter("scene.tools.gripper_kp", "gripper cable position-loop gain", "N/m", "assumed",
              "a small servo's stiffness at the cable; the grip force is the force limit, not kp (scene_options.py)",
              (200.0, 800.0)),
    Parameter("scene.tools.gripper_damping", "damping of each jaw's slide", "N·s/m", "assumed",
              "slide friction of printed jaws on their rails (scene_options.py)", (0.5, 8.0), log=True),
    Parameter("scene.tools.gripper_spring", "gripper jaw opening-spring rate", "N/m", "assumed",
              "light return spring (scene_options.py)", (10.0, 40.0)),
    Parameter("scene.tools.gripper_max_force", "gripper cable tension limit", "N", "assumed",
              "the foam sample weighs < 1 g; a small servo's pull", (1.0, 4.0)),
    Parameter("scene.tools.gripper_cable_speed", "gripper motor speed limit on its cable", "m/s", "assumed",
              "a small gear motor (scene_options.py)", (0.02, 0.1)),
    Parameter("scene.tools.pad_friction", "jaw pad sliding friction on foam", "1", "assumed",
              "rubber/printed pad on rigid PU foam, 0.5-1.5", (0.5, 1.5)),
    Parameter("scene.tools.pad_solref.0", "jaw pad contact time constant (MuJoCo solref)", "s", "assumed",
              "stiff enough that the 2 N grip sinks ~1 mm into the sample (scene_options.py)", (0.004, 0.016)),
    Parameter("scene.tools.pad_solref.1", "jaw pad contact damping ratio (MuJoCo solref)", "1", "assumed",
              "critically damped, MuJoCo's default", (0.5, 2.0)),
    Parameter("scene.tools.pad_solimp.1", "jaw pad contact impedance at full width (MuJoCo solimp dwidth)", "1", "assumed",
              "near-hard, from d0 = 0.95 to 0.99 over 1 mm; harder (0.999) tripled the solver iterations while carrying "
              "(scene_options.py)", (0.95, 0.999)),
    Parameter("scene.tools.pad_torsional_friction", "jaw pad torsional friction (MuJoCo friction[1])", "m", "assumed",
              "MuJoCo's default; resists the sample spinning about the contact normal", (0.001, 0.02), log=True),
    Parameter("scene.tools.pad_rolling_friction", "jaw pad rolling friction (MuJoCo friction[2])", "m", "assumed",
              "MuJoCo's default; resists the sample rolling on a pad", (1e-5, 1e-3), log=True),
    Parameter("layout.grasp.depth", "grasp depth of the pads over the plate edge", "m", "assumed",
              "the pads' 20 mm length over a 50 mm sample (layout.py)", (0.008, 0.016)),
    # ------------------------------------------------------------ foam and cutting
    Parameter("scene.foam.specific_energy", "foam specific cutting energy u at the reference density", "J/m³", "assumed",
              "3 × the compressive strength of ~30 kg/m³ rigid PU foam; band 0.13-2 MJ/m³ from the crushing bound "
              "and particleboard milling scaled by density (docs/cutting.md, reference/fidelity-notes.md)",
              (1.3e5, 2.0e6), log=True),
    Parameter("scene.foam.density_exponent", "exponent of u ∝ ρ^n", "1", "assumed",
              "Gibson-Ashby crushing strength ∝ (ρ*/ρs)^1.5, assumed to carry over to cutting; linear (1) to 2",
              (1.0, 2.0)),
    Parameter("scene.foam.radial_ratio", "radial to tangential cutting force ratio K_r/K_t", "1", "assumed",
              "metals 0.2-0.6 with sharp edges; a blunt burr ploughs more (scene_options.py)", (0.2, 1.0)),
    Parameter("scene.foam.block_stiffness", "uncut foam's stiffness against a cutter that does not cut", "N/m", "assumed",
              "numerically stable at 4 ms (scene_options.py)", (500.0, 8000.0), log=True),
    Parameter("scene.foam.min_cutting_speed", "slowest spindle speed that cuts (slower rubs)", "rad/s", "assumed",
              "5 % of the nominal 1000 rad/s: below it the burr rubs instead of cutting (docs/cutting.md)", (20.0, 200.0),
              log=True),
    Parameter("scene.foam.block_damping", "uncut foam's damping against a cutter that does not cut", "N·s/m", "assumed",
              "with block_stiffness, a stiff but numerically quiet wall at 4 ms (scene_options.py)", (2.0, 50.0), log=True),
    Parameter("scene.foam_friction", "foam sliding friction (plate, sample)", "1", "assumed",
              "printed/metal parts on rigid PU foam, 0.5-1.5", (0.5, 1.5)),
    Parameter("scene.foam_torsional_friction", "foam torsional friction (MuJoCo friction[1]; plate, sample)", "m", "assumed",
              "MuJoCo's default", (0.001, 0.02), log=True),
    Parameter("scene.foam_rolling_friction", "foam rolling friction (MuJoCo friction[2]; plate, sample)", "m", "assumed",
              "MuJoCo's default", (1e-5, 1e-3), log=True),
    Parameter("scene.weld_damping_ratio", "damping ratio of the weld holding the sample until cut free (MuJoCo solref)", "1",
              "assumed", "critically damped glue; its time constant is 2 × the timestep, the stiffest MuJoCo keeps stable",
              (0.5, 2.0)),
    Parameter("scene.weld_solimp.1", "impedance of the sample weld at full width (MuJoCo solimp dwidth)", "1", "assumed",
              "near-hard glue, from d0 = 0.99 (model/scene.py)", (0.99, 0.9999)),
    Parameter("layout.plate.density", "foam plate density", "kg/m³", "assumed",
              "rigid polyurethane insulation foam, 28-40 kg/m³ (BRUFMA, CAN/ULC S705.1)", (25.0, 40.0)),
    Parameter("layout.plate.contact_solref.0", "foam contact time constant (MuJoCo solref)", "s", "assumed",
              "soft foam contact (layout.py); 2× either way", (0.005, 0.02)),
    Parameter("layout.plate.contact_solref.1", "foam contact damping ratio (MuJoCo solref)", "1", "assumed",
              "critically damped, MuJoCo's default", (0.5, 2.0)),
    Parameter("layout.plate.contact_solimp.1", "foam contact impedance at full width (MuJoCo solimp dwidth)", "1", "assumed",
              "soft foam, from d0 = 0.9 to 0.95 over 2 mm (layout.py)", (0.9, 0.99)),
    # ------------------------------------------------------------ the task's motion
    Parameter("plan.cut_speed", "feed along the kerf", "m/s", "assumed",
              "slow feed on the cut (paper §5.2 gives no figure)", (0.0025, 0.01)),
    Parameter("plan.fast_speed", "tool speed off the cut (approach, carry, return)", "m/s", "assumed",
              "Cartesian moves off the cut; the gripper's final grasp move runs at half of it; the paper gives no figure",
              (0.02, 0.06)),
    Parameter("plan.joint_speed_deg_s", "joint-space transfer speed (bending coordinates, per section)", "deg/s", "assumed",
              "the transfers between key poses, e.g. the gripper's move to its pre-grasp pose; the paper gives no figure",
              (10.0, 40.0)),
]

REGISTRY: tuple[Parameter, ...] = tuple(_ENTRIES)
_BY_PATH: dict[str, Parameter] = {p.path: p for p in REGISTRY}


# ------------------------------------------------------------------------ queries
def parameter(path: str) -> Parameter:
    """The entry at ``path``; ``ConfigError`` naming the path (and a near miss) if there is none."""
    entry = _BY_PATH.get(path)
    if entry is None:
        note = migration_note(path)
        if note is not None:  # a removed or renamed field: say what replaces it
            raise ConfigError(path, note)
        import difflib

        close = difflib.get_close_matches(path, list(_BY_PATH), n=1)
        hint = f"; did you mean {close[0]}?" if close else ""
        raise ConfigError(path, f"not a registry parameter ({len(REGISTRY)} known; `continuum-sim params` lists them){hint}")
    return entry


def assumed() -> tuple[Parameter, ...]:
    """The assumed parameters (each with a range): what sensitivity studies and optimisers sample."""
    return tuple(p for p in REGISTRY if p.status == "assumed")


def with_range() -> tuple[Parameter, ...]:
    return tuple(p for p in REGISTRY if p.range is not None)


def values(config: Any) -> dict[str, float]:
    """Every parameter's value in ``config``, by path (the values the plant uses)."""
    return {p.path: p.value(config) for p in REGISTRY}


def parse_value(path: str, text: str) -> float:
    """A number given on the command line for ``path``; ``ConfigError`` naming the field if it is not one."""
    entry = parameter(path)
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(path, f"must be a number{_range_hint(entry)} (got {text[:40]!r})") from None
    if not math.isfinite(value):
        raise ConfigError(path, f"must be a finite number{_range_hint(entry)} (got {text[:40]!r})")
    return value


def _unit(entry: Parameter) -> str:
    return "" if entry.unit == "1" else f" {entry.unit}"


def _range_hint(entry: Parameter) -> str:
    if entry.range is None:
        return f" ({entry.unit})"
    low, high = entry.range
    return f" in [{low:g}, {high:g}]{_unit(entry)}"


def check_value(path: str, value: float) -> None:
    """Raise ``ConfigError`` (naming the field and its plausible range) for a value outside it."""
    entry = parameter(path)
    if not entry.in_range(value):
        assert entry.range is not None
        low, high = entry.range
        raise ConfigError(path, f"must satisfy {low:g} <= value <= {high:g}{_unit(entry)}, its plausible range (got {value:g})")


def apply(config: Any, overrides: Mapping[str, float], *, check_range: bool = True) -> Any:
    """``config`` with registry parameters set; every path and value is checked (``ConfigError``).

    ``check_range``: refuse values outside the plausible range (the CLI's ``--set``);
    the config's own validation applies in any case.
    """
    for path, value in overrides.items():
        entry = parameter(path)
        if check_range:
            check_value(path, value)
        current = get_path(config, entry.path)
        typed: float | int = int(round(value)) if isinstance(current, int) and not isinstance(current, bool) else float(value)
        config = replace_path(config, entry.path, typed)
    return config


def parse_overrides(items: list[str] | tuple[str, ...]) -> dict[str, float]:
    """``["PATH=VALUE", ...]`` → ``{path: value}``; malformed or unknown items are ``ConfigError``."""
    out: dict[str, float] = {}
    for item in items:
        path, sep, text = item.partition("=")
        path = path.strip()
        if not sep or not path:
            raise ConfigError("--set", f"must be PATH=VALUE, e.g. model.cable_friction.mu=0.1 (got {item[:60]!r})")
        out[path] = parse_value(path, text.strip())
    return out


def records(config: Any, default: Any, overrides: Mapping[str, float] | None = None) -> dict[str, Any]:
    """The ``parameters.json`` document of a run: every registry value in ``config`` and what differs from ``default``.

    ``overrides``: what the user set explicitly; None = every parameter whose value differs from ``default``.
    """
    now, base = values(config), values(default)
    if overrides is None:
        overrides = {path: v for path, v in now.items() if v != base[path]}
    return {
        "parameters": [
            {
                "path": p.path,
                "name": p.name,
                "value": now[p.path],
                "default": base[p.path],
                "unit": p.unit,
                "status": p.status,
                "source": p.source,
                "range": None if p.range is None else list(p.range),
                "log": p.log,
                "overridden": p.path in overrides,
            }
            for p in REGISTRY
        ],
        "overrides": dict(overrides),
    }


def registry_sha256() -> str:
    """sha256 of the registry table's metadata (path, unit, status, source, range, log of every parameter, in order)
    as canonical JSON: ``provenance.json``'s ``hashes.registry``."""
    import hashlib
    import json

    table = [{"path": p.path, "unit": p.unit, "status": p.status, "source": p.source,
              "range": None if p.range is None else [float(x) for x in p.range], "log": p.log} for p in REGISTRY]
    return hashlib.sha256(json.dumps(table, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode("utf-8")).hexdigest()
