"""Option dataclasses of the scene and its tools: light (no MuJoCo, no dm_control, no scipy).

``scenario.config`` loads these, so reading a configuration imports no simulator. The
builders that use them live in ``tools`` and ``scene`` (the runtime in ``plant``), which
re-export them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..configio import ConfigError, require_int, require_positive, require_range, require_solimp, require_solref


@dataclass(frozen=True)
class ToolOptions:
    """Tool details the paper does not give (*assumed*; all SI units)."""

    housing_radius: float = 0.015  # grinder housing radius (inside the distal disk)
    cutter_length: float = 0.020  # cutting cylinder length; must exceed plate thickness + overtravel
    spindle_speed: float = 1000.0  # rad/s, nominal command (~9500 rpm)
    spindle_max_speed: float = 2000.0  # rad/s, actuator ctrl range upper end
    spindle_kv: float = 1.0e-3  # N·m·s/rad, proportional gain of the spindle speed loop (MuJoCo velocity actuator)
    # Integral gain of the speed loop: corner at ki/kv = 20 rad/s, far below the P loop's
    # bandwidth kv/J ≈ 500 rad/s (J ≈ armature + cutter), so the PI adds no overshoot to speak of.
    spindle_ki: float = 0.02  # N·m/rad
    # Torque limit of the spindle motor (assumed): a 5 W micro motor at the nominal 1000 rad/s
    # (the class of a 380-size DC motor behind a flexible shaft); it spins the rotor up in
    # ~0.4 s (the plan's dwell_spin_up is 1 s). Foam cutting at the defaults needs ~2.5e-4 N·m.
    spindle_max_torque: float = 0.005  # N·m
    # Stalled: slower than this fraction of the command for this long (spin-up passes half
    # speed in ~0.2 s; a load past the limit drives the speed to zero, the cutting torque
    # P/ω growing as it falls).
    spindle_stall_fraction: float = 0.5
    spindle_stall_time: float = 0.5  # s
    spindle_armature: float = 2.0e-6  # kg·m², rotor + flexible shaft (a micro motor's rotor is ~1e-6)
    gripper_open_gap: float = 0.030  # pad-to-pad gap with the jaws open
    gripper_jaw_travel: float = 0.0125  # per jaw, closing
    gripper_pad_length: float = 0.020  # pad extent along tool z (centred on the TCP)
    gripper_pad_width: float = 0.016  # pad extent along tool y
    # Pad thickness: the finger plates stand this far behind the pad faces, clear of a plate
    # gripped at the grasp tilt (30° over the 12 mm grasp depth brings it ~8 mm closer).
    gripper_pad_thickness: float = 0.010
    gripper_spring: float = 20.0  # N/m, opening spring per jaw
    # N, the opening spring's force on a jaw at its open stop. It must hold the jaw (about
    # 24 g: 0.24 N) open in any orientation of the tool: without it (0) a tilted tool's jaw
    # slid 5–13 mm closed under gravity during the approach, its pad met the sample before
    # the grasp point and stopped the arm 18 mm short (docs/plant.md). 0.5 N = 2× the jaw's
    # weight; at full travel the springs then ask 0.75 N of the 2 N cable.
    gripper_preload: float = 0.5
    gripper_damping: float = 2.0  # N·s/m per jaw
    gripper_kp: float = 400.0  # N/m, cable position-loop gain
    gripper_max_force: float = 2.0  # N, largest cable tension (foam sample < 1 g)
    gripper_cable_speed: float = 0.05  # m/s, the gripper motor's speed limit on its cable command
    pad_friction: float = 1.0  # sliding friction of the jaw pads
    # Pad contact (wins over the foam's soft contact): stiff enough that the 2 N grip sinks
    # ~1 mm into the 0.7 g sample. MuJoCo scales contact softness by the bodies' masses;
    # with the foam's own parameters the pads sank 3-5 mm and the jaws closed onto their
    # stops. Harder still (0.99, 0.999) tripled the solver iterations while carrying.
    pad_solref: tuple[float, float] = (0.008, 1.0)
    pad_solimp: tuple[float, float, float] = (0.95, 0.99, 0.001)
    # The pads' torsional and rolling friction (MuJoCo's 2nd and 3rd friction coefficients):
    # MuJoCo's defaults; they only resist spin and rolling of the gripped sample about the contact.
    pad_torsional_friction: float = 0.005  # m
    pad_rolling_friction: float = 0.0001  # m
    # How the tools' masses (model.grinder_mass, model.gripper_mass) are split over their bodies:
    # grinder: the housing (bearings, holder) takes this share, the spindle the rest, of which
    # the bare shaft takes grinder_shaft_fraction and the cutter the remainder; gripper: the palm
    # (pulley, slides) takes this share, each jaw half the rest, of which its pad takes
    # gripper_pad_fraction and its finger plate the remainder.
    grinder_housing_fraction: float = 0.85
    grinder_shaft_fraction: float = 0.2
    gripper_palm_fraction: float = 0.6
    gripper_pad_fraction: float = 0.2
    # A jaw's slide: reflected inertia of its pulley and slide (kg, regularises the light jaw)
    # and its end stops (MuJoCo solreflimit (time constant, damping ratio) and solimplimit
    # (d0, dwidth, width)): hard stops; the default soft limit let a jaw overrun by 3 mm at full grip force.
    gripper_jaw_armature: float = 1e-4
    gripper_stop_solref: tuple[float, float] = (0.01, 1.0)
    gripper_stop_solimp: tuple[float, float, float] = (0.95, 0.99, 0.001)

    def __post_init__(self) -> None:
        require_range("housing_radius", self.housing_radius, 0.0, 0.1)
        require_range("cutter_length", self.cutter_length, 0.0, 0.5)
        require_range("spindle_speed", self.spindle_speed, 0.0, self.spindle_max_speed, low_inclusive=True)
        require_range("spindle_max_speed", self.spindle_max_speed, 0.0, 1.0e5)
        require_positive("spindle_kv", self.spindle_kv)
        require_range("spindle_ki", self.spindle_ki, 0.0, 10.0, low_inclusive=True)
        require_range("spindle_max_torque", self.spindle_max_torque, 0.0, 10.0)
        require_range("spindle_stall_fraction", self.spindle_stall_fraction, 0.0, 1.0)
        require_range("spindle_stall_time", self.spindle_stall_time, 0.0, 10.0)
        require_range("spindle_armature", self.spindle_armature, 0.0, 1.0, low_inclusive=True)
        require_range("gripper_open_gap", self.gripper_open_gap, 0.0, 0.3)
        require_range("gripper_jaw_travel", self.gripper_jaw_travel, 0.0, self.gripper_open_gap / 2, high_inclusive=False)
        require_range("gripper_pad_length", self.gripper_pad_length, 0.0, 0.2)
        require_range("gripper_pad_width", self.gripper_pad_width, 0.0, 0.2)
        require_range("gripper_pad_thickness", self.gripper_pad_thickness, 0.0, 0.05)
        require_range("gripper_spring", self.gripper_spring, 0.0, 1.0e5, low_inclusive=True)
        require_range("gripper_preload", self.gripper_preload, 0.0, 100.0, low_inclusive=True)
        require_range("gripper_damping", self.gripper_damping, 0.0, 1.0e4, low_inclusive=True)
        require_positive("gripper_kp", self.gripper_kp)
        require_positive("gripper_max_force", self.gripper_max_force)
        require_positive("gripper_cable_speed", self.gripper_cable_speed)
        require_solref("pad_solref", self.pad_solref)
        require_solimp("pad_solimp", self.pad_solimp)
        require_range("pad_friction", self.pad_friction, 0.0, 10.0, low_inclusive=True)
        require_range("pad_torsional_friction", self.pad_torsional_friction, 0.0, 1.0, low_inclusive=True)
        require_range("pad_rolling_friction", self.pad_rolling_friction, 0.0, 1.0, low_inclusive=True)
        for name in ("grinder_housing_fraction", "grinder_shaft_fraction", "gripper_palm_fraction", "gripper_pad_fraction"):
            require_range(name, getattr(self, name), 0.0, 1.0, high_inclusive=False)
        require_range("gripper_jaw_armature", self.gripper_jaw_armature, 0.0, 1.0, low_inclusive=True)
        require_solref("gripper_stop_solref", self.gripper_stop_solref)
        require_solimp("gripper_stop_solimp", self.gripper_stop_solimp)
        # The cable must out-pull the opening springs at full travel, or the jaws never close.
        most = self.gripper_max_force - self.gripper_spring * self.gripper_jaw_travel
        if self.gripper_preload >= most:
            raise ConfigError(
                "gripper_preload",
                f"must satisfy 0 <= gripper_preload < gripper_max_force - gripper_spring * gripper_jaw_travel = {most:.3g} N "
                f"(got {self.gripper_preload:g}): the cable could not close the jaws",
            )

    @property
    def gripper_closed_gap(self) -> float:
        """Smallest pad-to-pad gap (both jaws at full travel)."""
        return self.gripper_open_gap - 2 * self.gripper_jaw_travel

    @property
    def gripper_cable_open(self) -> float:
        """Cable command that lets the springs open the jaws fully."""
        return 0.0

    @property
    def gripper_cable_closed(self) -> float:
        """Cable command past full closure by twice the force limit's stretch (Fmax / kp).

        Whatever the jaws' positions on the object (one may rest on its end stop when the
        object sits off-centre), the position loop then saturates: the grip force is the
        force limit, not the small remainder of a command that ends at full closure.
        """
        return -2 * self.gripper_jaw_travel - 2 * self.gripper_max_force / self.gripper_kp

    def gripper_cable_for_gap(self, gap: float) -> float:
        """Cable command (tendon length) that closes the pads to ``gap`` (clipped to travel)."""
        gap = min(max(gap, self.gripper_closed_gap), self.gripper_open_gap)
        return gap - self.gripper_open_gap


@dataclass(frozen=True)
class FoamOptions:
    """The foam's cutting properties and the voxel model (values and sources: docs/cutting.md)."""

    # Specific cutting energy u = K_t at reference_density (assumed): 3 × the compressive
    # strength of rigid PU insulation foam of ~30 kg/m³ (≥ 150 kPa, BS 4841 boards per BRUFMA;
    # ≥ 170 kPa for 28 kg/m³ spray foam, CAN/ULC S705.1), the ratio u/σ_y ≈ 3 that metals show
    # (Al 6061: σ_y 275 MPa, u ≈ 0.7-1 J/mm³).
    specific_energy: float = 0.5e6  # J/m³
    reference_density: float = 30.0  # kg/m³
    # u ∝ ρ^1.5: the Gibson–Ashby scaling of a cellular solid's crushing strength (Cellular
    # Solids, 1997, σ_pl ∝ (ρ*/ρ_s)^1.5), assumed to carry over to cutting.
    density_exponent: float = 1.5
    radial_ratio: float = 0.5  # K_r/K_t (assumed; metals 0.2-0.6 with sharp edges, a blunt burr ploughs more)
    voxel_size: float = 0.001  # m, target edge (rounded so whole voxels tile the plate)
    engagement_points: int = 24  # angles on the leading half circle
    recent_window: float = 0.25  # s of cutter positions remembered exactly (sub-voxel jitter makes no chip)
    min_cutting_speed: float = 50.0  # rad/s: a slower spindle rubs instead of cutting
    block_stiffness: float = 2000.0  # N/m, uncut foam against a cutter that does not cut (assumed, numerically stable at 4 ms)
    block_damping: float = 10.0  # N·s/m
    # s between connectivity checks (only after material was removed): ~0.1 ms each at 1 mm (plant/foam.py's flood fill)
    connectivity_period: float = 0.1
    grip_radius: float = 0.006  # m: the material under the jaws, around the grasp point

    def __post_init__(self) -> None:
        require_positive("specific_energy", self.specific_energy)
        require_positive("reference_density", self.reference_density)
        require_range("density_exponent", self.density_exponent, 0.0, 5.0, low_inclusive=True)
        require_range("radial_ratio", self.radial_ratio, 0.0, 5.0, low_inclusive=True)
        require_range("voxel_size", self.voxel_size, 0.0002, 0.01, low_inclusive=True)
        require_int("engagement_points", self.engagement_points, 4, 1000)
        require_range("recent_window", self.recent_window, 0.0, 5.0, low_inclusive=True)
        require_range("min_cutting_speed", self.min_cutting_speed, 0.0, 1.0e4, low_inclusive=True)
        require_range("block_stiffness", self.block_stiffness, 0.0, 1.0e6, low_inclusive=True)
        require_range("block_damping", self.block_damping, 0.0, 1.0e4, low_inclusive=True)
        require_range("connectivity_period", self.connectivity_period, 0.0, 10.0, low_inclusive=True)
        require_range("grip_radius", self.grip_radius, 0.0, 0.1)

    def cutting_energy(self, density: float) -> float:
        """u (J/m³) of a foam of ``density`` (kg/m³)."""
        return self.specific_energy * (density / self.reference_density) ** self.density_exponent


@dataclass(frozen=True)
class SceneOptions:
    """Scene details beyond the task layout (*assumed*; SI units)."""

    tools: ToolOptions = field(default_factory=ToolOptions)
    foam: FoamOptions = field(default_factory=FoamOptions)  # what the cutter cuts (voxels, cutting energy)
    sample_gap: float = 0.0002  # clearance between the sample's box and the plate's boxes
    foam_friction: float = 1.0
    # The foam's (plate, sample) torsional and rolling friction: MuJoCo's defaults (m).
    foam_torsional_friction: float = 0.005
    foam_rolling_friction: float = 0.0001
    # The weld holding the sample to the plate until it is cut free: its solref time constant
    # is 2 × the timestep (the stiffest MuJoCo keeps stable: glue, not foam); these are the
    # rest of it, the damping ratio and the impedance (d0, dwidth, width), near-hard.
    weld_damping_ratio: float = 1.0
    weld_solimp: tuple[float, float, float] = (0.99, 0.999, 0.001)
    bench_height: float = 0.75  # floor is this far below the bench top (= pack bottom)
    render_width: int = 1280
    render_height: int = 720
    # False: the gripper's bodies pass through the fixed plate (its two boxes; the sample still
    # collides, so the jaws can grasp it). An attribution switch (docs/calibration.md): what the
    # gripper meeting the plate on its approach costs the open loop.
    gripper_plate_contact: bool = True

    def __post_init__(self) -> None:
        require_range("sample_gap", self.sample_gap, 0.0, 0.002, low_inclusive=True)
        require_range("foam_friction", self.foam_friction, 0.0, 10.0, low_inclusive=True)
        require_range("foam_torsional_friction", self.foam_torsional_friction, 0.0, 1.0, low_inclusive=True)
        require_range("foam_rolling_friction", self.foam_rolling_friction, 0.0, 1.0, low_inclusive=True)
        require_positive("weld_damping_ratio", self.weld_damping_ratio)
        require_solimp("weld_solimp", self.weld_solimp)
        require_range("bench_height", self.bench_height, 0.05, 3.0, low_inclusive=True)
        require_int("render_width", self.render_width, 16, 8192)
        require_int("render_height", self.render_height, 16, 8192)


# ------------------------------------------------------------------ small helpers
