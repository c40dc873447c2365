"""Where things stand in the sample-removal task (SPEC §5): the one place for the layout.

The planner (toolpaths, workspace check) and the MuJoCo scene builder both read this,
so the plate the grinder plans against is the plate the simulation collides with.
World frame: z up, gravity −z, actuation pack top face at z = 0, arms along +z.

Default layout (*assumed*, SPEC §5): a horizontal foam plate above and in front of the
pack; its free corner sticks into the arms' cooperative workspace. The sample is the
rectangular corner ``x ∈ [corner_x − sample_x, corner_x]``, ``y ∈ [corner_y,
corner_y + sample_y]``, cut off by an L-shaped kerf: from the plate's front edge
(y = corner_y) along +y to the sample's inner corner, then along +x out through the
side edge (x = corner_x). The grinder (left arm) cuts from below with its spindle
vertical (the plate normal); the gripper (right arm) holds the corner from the side,
its jaws closing across the plate thickness.

Why these numbers (checked with ``continuum-sim workspace`` and the IK): with the
spindle vertical, the grinder's tool point can only be at heights in a ~6 cm band that
falls with the distance from its base (0.54-0.58 m at 0.1 m, 0.44-0.51 m at 0.25 m), so
the kerf sits high (plate top at 0.54 m) and 0.09-0.19 m from the left arm's axis. A
horizontal gripper tool needs ~90° of total bending, which keeps its tool point below
~0.47 m near its base; at 0.535 m it reaches the side edge only with its tool axis
tilted 30° above horizontal (``GraspLayout.tilt_deg``). The arms' straight poses stay
clear of the plate (corner at y = 0.05 m, x = 0.05 m).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .configio import ConfigError, require_positive, require_range, require_solimp, require_solref

ARMS = ("left", "right")  # the two arms, in the order every per-arm array and loop uses
TOOLS = ("grinder", "gripper")


@dataclass(frozen=True)
class ArmMount:
    """An arm's base frame in the world: position of disk 0's centre, arm along +z."""

    position: tuple[float, float, float]
    tool: str

    def __post_init__(self) -> None:
        for i, value in enumerate(self.position):
            require_range(f"position[{i}]", value, -5.0, 5.0)
        if self.tool not in ("grinder", "gripper"):
            raise ConfigError("tool", f"must be 'grinder' or 'gripper' (got {self.tool!r})")

    def base_transform(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, 3] = self.position
        return T


@dataclass(frozen=True)
class PlateLayout:
    """The foam plate, its sample corner and the kerf (metres)."""

    size: tuple[float, float, float] = (0.200, 0.150, 0.010)  # x, y, thickness
    corner_x: float = 0.050  # the free corner (max x, min y) of the plate
    corner_y: float = 0.050
    top_z: float = 0.540  # height of the plate's top face
    sample_x: float = 0.050  # sample extent from the corner along −x
    sample_y: float = 0.050  # … and along +y
    kerf_width: float = 0.010  # width of the cut (the cutter diameter)
    cut_overtravel: float = 0.003  # how far the cutter tip passes the top face
    # Soft foam contact (MuJoCo solref timeconst/damping ratio, solimp); documented in README.
    contact_solref: tuple[float, float] = (0.01, 1.0)
    contact_solimp: tuple[float, float, float] = (0.9, 0.95, 0.002)
    density: float = 30.0  # kg/m³, rigid polyurethane foam

    def __post_init__(self) -> None:
        for i, value in enumerate(self.size):
            require_range(f"size[{i}]", value, 0.0, 2.0)
        require_range("top_z", self.top_z, 0.0, 3.0)
        require_range("sample_x", self.sample_x, 0.0, self.size[0], high_inclusive=False)
        require_range("sample_y", self.sample_y, 0.0, self.size[1], high_inclusive=False)
        require_range("kerf_width", self.kerf_width, 0.0, min(self.sample_x, self.sample_y))
        require_range("cut_overtravel", self.cut_overtravel, 0.0, 0.05, low_inclusive=True)
        require_solref("contact_solref", self.contact_solref)
        require_solimp("contact_solimp", self.contact_solimp)
        require_positive("density", self.density)

    @property
    def thickness(self) -> float:
        return self.size[2]

    @property
    def centre(self) -> np.ndarray:
        """Centre of the whole (uncut) plate."""
        return np.array(
            [self.corner_x - self.size[0] / 2, self.corner_y + self.size[1] / 2, self.top_z - self.size[2] / 2]
        )

    @property
    def sample_centre(self) -> np.ndarray:
        return np.array(
            [self.corner_x - self.sample_x / 2, self.corner_y + self.sample_y / 2, self.top_z - self.size[2] / 2]
        )

    def kerf_polyline(self) -> np.ndarray:
        """(3, 3) cut centre line on the top face: front edge → inner corner → side edge.

        The kerf runs along the sample's boundary, offset by half a kerf width into the
        plate so the sample keeps its nominal size.
        """
        h = self.kerf_width / 2
        x_in = self.corner_x - self.sample_x - h
        y_in = self.corner_y + self.sample_y + h
        return np.array(
            [
                [x_in, self.corner_y, self.top_z],
                [x_in, y_in, self.top_z],
                [self.corner_x, y_in, self.top_z],
            ]
        )


@dataclass(frozen=True)
class GraspLayout:
    """Where and how the gripper holds the sample: on the side edge (x = corner_x).

    The jaws close along the tool x axis; the tool z points at the edge (world −x). The
    ideal is tool z horizontal and x vertical; with the default arm mounts the right arm
    cannot bend 90° that high up, so the approach is tilted: tool z points ``tilt_deg``
    above the horizontal (coming from below) and the jaws close ``tilt_deg`` off vertical.
    """

    tilt_deg: float = 30.0
    depth: float = 0.012  # TCP (pad centre) this far inside the side edge
    edge_offset: float = 0.018  # TCP this far along +y from the plate's front edge

    def __post_init__(self) -> None:
        require_range("tilt_deg", self.tilt_deg, -60.0, 60.0, low_inclusive=True)
        require_range("depth", self.depth, 0.0, 0.1)
        require_range("edge_offset", self.edge_offset, 0.0, 1.0)

    def rotation(self) -> np.ndarray:
        """World rotation of the gripper tool frame at the grasp (columns x, y, z)."""
        t = np.radians(self.tilt_deg)
        z = np.array([-np.cos(t), 0.0, np.sin(t)])
        x = np.array([np.sin(t), 0.0, np.cos(t)])
        return np.column_stack([x, np.cross(z, x), z])


@dataclass(frozen=True)
class TaskLayout:
    """Both arm mounts, the plate, and the clamp post that holds the plate's far end."""

    left: ArmMount = field(default_factory=lambda: ArmMount((-0.10, 0.0, 0.0), "grinder"))
    right: ArmMount = field(default_factory=lambda: ArmMount((0.10, 0.0, 0.0), "gripper"))
    plate: PlateLayout = field(default_factory=PlateLayout)
    pack_size: tuple[float, float, float] = (0.36, 0.16, 0.12)  # actuation pack box below z = 0
    clamp_length: float = 0.040  # clamped strip along the plate's far x edge
    grasp: GraspLayout = field(default_factory=GraspLayout)

    def __post_init__(self) -> None:
        if self.left.tool != "grinder" or self.right.tool != "gripper":
            raise ConfigError("left.tool", "the left arm carries the grinder and the right arm the gripper")
        for i, value in enumerate(self.pack_size):
            require_range(f"pack_size[{i}]", value, 0.0, 5.0)
        require_range("clamp_length", self.clamp_length, 0.0, self.plate.size[0] - self.plate.sample_x)
        if self.grasp.edge_offset >= self.plate.sample_y:
            raise ConfigError(
                "grasp.edge_offset",
                f"must satisfy 0 < edge_offset < plate.sample_y = {self.plate.sample_y:g} (the jaws hold the sample; "
                f"got {self.grasp.edge_offset:g})",
            )
        if self.grasp.depth >= self.plate.sample_x:
            raise ConfigError("grasp.depth", f"must satisfy 0 < depth < plate.sample_x = {self.plate.sample_x:g} (got {self.grasp.depth:g})")

    def grasp_pose(self) -> np.ndarray:
        """World pose of the gripper TCP holding the sample (4, 4)."""
        T = np.eye(4)
        T[:3, :3] = self.grasp.rotation()
        plate = self.plate
        T[:3, 3] = [plate.corner_x - self.grasp.depth, plate.corner_y + self.grasp.edge_offset, plate.top_z - plate.thickness / 2]
        return T

    def arm_for(self, tool: str) -> str:
        """The arm that carries ``tool`` (the one place the arm<->tool pairing is read)."""
        for arm in ARMS:
            if self.mount(arm).tool == tool:
                return arm
        raise ConfigError("tool", f"no arm carries a {tool!r} (tools: {', '.join(self.mount(a).tool for a in ARMS)})")

    def tool_of(self, arm: str) -> str:
        """The tool ``arm`` carries."""
        return self.mount(arm).tool

    def mount(self, arm: str) -> ArmMount:
        if arm == "left":
            return self.left
        if arm == "right":
            return self.right
        raise ConfigError("arm", f"must be 'left' or 'right' (got {arm!r})")
