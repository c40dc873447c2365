"""The sample-removal scene (SPEC §5, §6): pack, bench, clamp, foam plate, tools, arms.

``build_scene`` is a pure function from configuration to an MJCF tree: it holds no
simulation state and composes the parts with ``site.attach()`` (dm_control style).
Runtime behaviour (material removed, the weld letting go) lives in ``cutting``.

World: z up, pack top face at z = 0, arms along +z from ``layout.left/right``. The
plate is static (clamped); its sample corner is a free body welded to it by the
equality ``sample_weld``. The plate's geoms (two boxes around the sample and the kerf
band, and the sample's box) are what the gripper, the arms and the carried sample touch;
the cutter collides with none of them: what it cuts is the voxel foam of
``plant.cutter.FoamCutter`` (``SceneOptions.foam``), which covers the whole plate outside the
clamp, sample and kerf band included. Foam contacts are soft
(``layout.plate.contact_solref/solimp``) and win over the other geom's parameters by
collision priority.

Names (after attachment): ``left/…`` grinder arm, ``right/…`` gripper arm, tendons and
actuators ``<arm>/cable_<section>_<c>``, sites ``<arm>/tcp``, spindle actuator
``left/grinder/spindle``, gripper cable tendon and actuator ``right/gripper/cable``,
cutter geom ``left/grinder/cutter``, bodies ``plate`` and ``sample``, equality
``sample_weld``, cameras ``overview`` and ``closeup``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dm_control import mjcf

from ..configio import ConfigError
from ..geometry import ArmGeometry
from ..layout import ARMS, TaskLayout
from . import tools as tools_mod
from .arm import apply_simulation_options, arm_collision_bits, build_arm
from .options import ModelOptions, model_geometry
from .scene_options import SceneOptions
from .tools import FOAM_PRIORITY

ArmBuilder = Callable[[ArmGeometry, ModelOptions, str, str], mjcf.RootElement]

SCENE_MODEL = "dual_arm"
PLATE_BODY = "plate"
SAMPLE_BODY = "sample"
SAMPLE_WELD = "sample_weld"
KERF_BAND = ("uncut_kerf_0", "uncut_kerf_1")  # visual-only geoms of the uncut kerf band
CAMERAS = ("overview", "closeup")


def look_at(position: np.ndarray, target: np.ndarray, up: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> tuple[float, ...]:
    """MJCF ``xyaxes`` of a camera at ``position`` looking at ``target`` (MuJoCo cameras look along −z)."""
    forward = np.asarray(target, float) - np.asarray(position, float)
    forward /= np.linalg.norm(forward)
    x = np.cross(forward, up)
    x /= np.linalg.norm(x)
    y = np.cross(x, forward)
    return tuple(float(v) for v in np.concatenate([x, y]))


def _plate_extents(layout: TaskLayout) -> dict[str, float]:
    plate = layout.plate
    ext = {
        "x0": plate.corner_x - plate.size[0],
        "x1": plate.corner_x,
        "y0": plate.corner_y,
        "y1": plate.corner_y + plate.size[1],
        "xk": plate.corner_x - plate.sample_x - plate.kerf_width,  # kerf band's outer x
        "yk": plate.corner_y + plate.sample_y + plate.kerf_width,  # kerf band's outer y
    }
    if ext["xk"] - ext["x0"] <= layout.clamp_length + 0.005:
        raise ConfigError(
            "plate.sample_x",
            f"sample plus kerf must leave more than clamp_length + 5 mm of plate to clamp "
            f"(plate {plate.size[0]:g} m, sample_x + kerf_width = {plate.sample_x + plate.kerf_width:g} m)",
        )
    if ext["yk"] >= ext["y1"]:
        raise ConfigError(
            "plate.sample_y",
            f"sample_y + kerf_width must be < plate width {plate.size[1]:g} m (got {plate.sample_y + plate.kerf_width:g})",
        )
    return ext


def _box(body: mjcf.Element, name: str, lo: tuple[float, float, float], hi: tuple[float, float, float], origin: np.ndarray, **kw) -> mjcf.Element:
    lo_a, hi_a = np.asarray(lo, float), np.asarray(hi, float)
    return body.add("geom", name=name, type="box", size=tuple((hi_a - lo_a) / 2), pos=tuple((hi_a + lo_a) / 2 - origin), **kw)


# ------------------------------------------------------------------ parts
def _add_assets_and_visuals(root: mjcf.RootElement, scene: SceneOptions) -> None:
    root.asset.add("texture", name="sky", type="skybox", builtin="gradient", rgb1=(0.3, 0.5, 0.7), rgb2=(0, 0, 0), width=512, height=3072)
    root.asset.add(
        "texture", name="floor", type="2d", builtin="checker", rgb1=(0.2, 0.3, 0.4), rgb2=(0.1, 0.2, 0.3), width=512, height=512, mark="cross", markrgb=(0.8, 0.8, 0.8)
    )
    root.asset.add("material", name="floor", texture="floor", texrepeat=(5, 5), texuniform=True, reflectance=0.1)
    root.asset.add("material", name="foam", rgba=(0.93, 0.86, 0.55, 1.0))
    root.asset.add("material", name="sample", rgba=(0.95, 0.55, 0.25, 1.0))
    root.asset.add("material", name="metal", rgba=(0.45, 0.47, 0.5, 1.0), specular=0.5, shininess=0.5)
    root.asset.add("material", name="wood", rgba=(0.55, 0.4, 0.28, 1.0))
    visual_global = getattr(root.visual, "global")  # `global` is a Python keyword
    visual_global.offwidth = scene.render_width
    visual_global.offheight = scene.render_height
    root.visual.quality.shadowsize = 4096
    root.visual.headlight.ambient = (0.25, 0.25, 0.25)
    root.visual.headlight.diffuse = (0.4, 0.4, 0.4)
    root.visual.map.znear = 0.005
    root.statistic.center = (0.0, 0.05, 0.3)
    root.statistic.extent = 0.9


def _add_environment(root: mjcf.RootElement, layout: TaskLayout, scene: SceneOptions) -> None:
    """Floor, bench, actuation pack, clamp post: static, default contact parameters."""
    px, py, pz = layout.pack_size
    bench_top = -pz
    floor_z = bench_top - scene.bench_height
    world = root.worldbody
    world.add("geom", name="floor", type="plane", size=(0, 0, 0.05), pos=(0, 0, floor_z), material="floor")
    world.add("light", name="key", pos=(0.3, -0.6, 1.6), dir=(-0.2, 0.4, -1.0), directional=True, castshadow=True, diffuse=(0.7, 0.7, 0.7))
    world.add("light", name="fill", pos=(-0.6, -0.4, 1.0), dir=(0.5, 0.4, -0.6), castshadow=False, diffuse=(0.3, 0.3, 0.3))

    # Bench top under the pack and the clamp, reaching past the plate; four legs.
    plate_y1 = layout.plate.corner_y + layout.plate.size[1]
    lo = np.array([-max(0.4, px / 2 + 0.1), -py / 2 - 0.1, bench_top - 0.03])
    hi = np.array([max(0.4, px / 2 + 0.1), max(py / 2, plate_y1) + 0.1, bench_top])
    bench = world.add("body", name="bench")
    _box(bench, "bench_top", tuple(lo), tuple(hi), np.zeros(3), material="wood")
    for i, (x, y) in enumerate(((lo[0] + 0.03, lo[1] + 0.03), (lo[0] + 0.03, hi[1] - 0.03), (hi[0] - 0.03, lo[1] + 0.03), (hi[0] - 0.03, hi[1] - 0.03))):
        _box(bench, f"bench_leg_{i}", (x - 0.02, y - 0.02, floor_z), (x + 0.02, y + 0.02, lo[2]), np.zeros(3), material="wood")
    pack = world.add("body", name="pack")
    pack.add("geom", name="pack", type="box", size=(px / 2, py / 2, pz / 2), pos=(0, 0, -pz / 2), material="metal")
    for arm in ARMS:
        mount = layout.mount(arm)
        pack.add("geom", name=f"{arm}_flange", type="cylinder", size=(0.03, 0.002), pos=(mount.position[0], mount.position[1], -0.002), rgba=(0.2, 0.2, 0.22, 1))

    # Clamp: a post from the bench to the plate's far strip, a lower and an upper jaw bar.
    plate = layout.plate
    ext = _plate_extents(layout)
    bottom = plate.top_z - plate.thickness
    clamp = world.add("body", name="clamp")
    post_half = np.array([min(0.02, layout.clamp_length / 2), 0.015])
    post_x = ext["x0"] + layout.clamp_length / 2
    post_y = max((ext["y0"] + ext["y1"]) / 2, py / 2 + post_half[1] + 0.01)
    post_y = min(post_y, ext["y1"] - post_half[1])
    bar = 0.008
    clamp.add(
        "geom",
        name="clamp_post",
        type="box",
        size=(post_half[0], post_half[1], (bottom - bar - bench_top) / 2),
        pos=(post_x, post_y, (bottom - bar + bench_top) / 2),
        material="metal",
    )
    origin = np.zeros(3)
    _box(clamp, "clamp_lower", (ext["x0"], ext["y0"], bottom - bar), (ext["x0"] + layout.clamp_length, ext["y1"], bottom), origin, material="metal")
    _box(clamp, "clamp_upper", (ext["x0"], ext["y0"], plate.top_z), (ext["x0"] + layout.clamp_length, ext["y1"], plate.top_z + bar), origin, material="metal")


def _add_plate(root: mjcf.RootElement, layout: TaskLayout, scene: SceneOptions, timestep: float) -> None:
    """Static plate (two boxes around the sample and the kerf band), welded sample."""
    plate = layout.plate
    ext = _plate_extents(layout)
    top, bottom = plate.top_z, plate.top_z - plate.thickness
    foam = dict(
        solref=plate.contact_solref,
        solimp=plate.contact_solimp,
        friction=(scene.foam_friction, scene.foam_torsional_friction, scene.foam_rolling_friction),
        priority=FOAM_PRIORITY,
    )
    origin = plate.centre
    body = root.worldbody.add("body", name=PLATE_BODY, pos=tuple(origin))
    _box(body, "plate_main", (ext["x0"], ext["y0"], bottom), (ext["xk"], ext["y1"], top), origin, material="foam", **foam)
    _box(body, "plate_side", (ext["xk"], ext["yk"], bottom), (ext["x1"], ext["y1"], top), origin, material="foam", **foam)
    # The kerf band is foam too (the voxels cut it), but no contact geom: the sample has to
    # leave through it. These two boxes only show it, as uncut foam (so no picture shows the
    # cut before it is made); the cutter hides them at detachment, and the video draws the
    # band from the cutter's voxels instead (``video_foam``).
    kerf_x = ext["xk"] + plate.kerf_width
    kerf_y = ext["yk"] - plate.kerf_width
    for name, lo, hi in (
        (KERF_BAND[0], (ext["xk"], ext["y0"], bottom), (kerf_x, ext["yk"], top)),
        (KERF_BAND[1], (kerf_x, kerf_y, bottom), (ext["x1"], ext["yk"], top)),
    ):
        _box(body, name, lo, hi, origin, material="foam", contype=0, conaffinity=0, mass=0)
    for name, p in zip(("kerf_start", "kerf_corner", "kerf_end"), plate.kerf_polyline()):
        body.add("site", name=name, pos=tuple(p - origin), size=(0.002,), rgba=(1, 0, 0, 0.6))

    # The sample: nominal corner rectangle, pulled back from the kerf by sample_gap on its
    # two inner sides (its outer sides stay flush with the plate edges).
    g = scene.sample_gap
    lo = np.array([plate.corner_x - plate.sample_x + g, plate.corner_y, bottom])  # type: ignore[assignment]
    hi = np.array([plate.corner_x, plate.corner_y + plate.sample_y - g, top])  # type: ignore[assignment]
    centre = (lo + hi) / 2  # type: ignore[operator]
    sample = root.worldbody.add("body", name=SAMPLE_BODY, pos=tuple(centre))  # type: ignore[arg-type]
    sample.add("freejoint", name=SAMPLE_BODY)
    sample.add("geom", name=SAMPLE_BODY, type="box", size=tuple((hi - lo) / 2), density=plate.density, material="sample", **foam)  # type: ignore[operator]
    sample.add("site", name="sample_centre", size=(0.002,), rgba=(0, 0, 1, 0.6))
    # Anchor at the sample's centre (given in the plate's frame): a weld anchored far away
    # lets a light body swing about the anchor. Stiff (5 timesteps): it is glue, not foam.
    root.equality.add(
        "weld",
        name=SAMPLE_WELD,
        body1=SAMPLE_BODY,
        body2=PLATE_BODY,
        anchor=tuple(centre - origin),
        solref=(2 * timestep, scene.weld_damping_ratio),
        solimp=(*scene.weld_solimp, 0.5, 2),
    )


def _add_cameras(root: mjcf.RootElement, layout: TaskLayout) -> None:
    plate = layout.plate
    kerf = plate.kerf_polyline()
    kerf_centre = kerf.mean(axis=0) - np.array([0.0, 0.0, plate.thickness / 2])
    # Overview, framed on the work (docs/video.md): the plate, the clamp, both tools and the
    # arms' upper sections, from the front right and above, so the floor (not the sky) is
    # behind the plate and the plate spans about half the tile's width.
    overview_target = plate.centre + np.array([0.03, -0.06, -0.04])
    overview_pos = overview_target + np.array([0.22, -0.34, 0.25])
    root.worldbody.add("camera", name="overview", pos=tuple(overview_pos), xyaxes=look_at(overview_pos, overview_target), fovy=45)
    # Close-up from above, in front: the cutter comes from below, so the slot it leaves opens
    # in the top face as the voxels go, and the arms do not block the view. The camera rides
    # with the sample (mode "track": a fixed offset in world axes from the sample body), so it
    # stays on the kerf while the sample is welded and follows the sample once it is cut free.
    target = (kerf_centre + plate.sample_centre) / 2
    close_pos = target + np.array([0.05, -0.12, 0.14])
    sample = root.worldbody.find("body", SAMPLE_BODY)
    sample.add("camera", name="closeup", mode="track", pos=tuple(close_pos - np.asarray(sample.pos, float)),
               xyaxes=look_at(close_pos, target), fovy=40)


def _attach_tool(
    arm: str,
    arm_model: mjcf.RootElement,
    tool: str,
    geometry: ArmGeometry,
    layout: TaskLayout,
    options: ModelOptions,
    scene: SceneOptions,
) -> mjcf.RootElement | None:
    """Attach ``tool`` at the arm's ``tool_mount`` with the arm's collision bits, so the
    tool (the cutter above all) never collides with its own arm but does with the world
    and the other arm."""
    plate = layout.plate
    tool_model = tools_mod.build_tool(
        tool,
        model_geometry(geometry, options),
        options,
        scene.tools,
        plate.kerf_width,
        arm_collision_bits(arm),
        pad_tilt_deg=layout.grasp.tilt_deg,
    )
    if tool_model is None:
        return None
    tool_mount = arm_model.find("site", "tool_mount")
    if tool_mount is None:
        raise ValueError(f"arm model {arm!r} has no 'tool_mount' site to attach the {tool} to")
    tool_mount.attach(tool_model)
    return tool_model


def _attach_arm(
    root: mjcf.RootElement,
    arm: str,
    geometry: ArmGeometry,
    layout: TaskLayout,
    options: ModelOptions,
    scene: SceneOptions,
    arm_builder: ArmBuilder,
) -> mjcf.RootElement:
    mount = layout.mount(arm)
    arm_model = arm_builder(geometry, options, arm, mount.tool)
    site = root.worldbody.add("site", name=f"{arm}_mount", pos=mount.position, size=(0.004,), rgba=(0, 1, 0, 0.5), group=5)
    site.attach(arm_model)
    tool_model = _attach_tool(arm, arm_model, mount.tool, geometry, layout, options, scene)
    if tool_model is not None and mount.tool == "gripper" and not scene.gripper_plate_contact:
        plate = root.worldbody.find("body", PLATE_BODY)
        for body in tool_model.find_all("body"):
            root.contact.add("exclude", body1=body, body2=plate)
    return arm_model


def build_scene(
    geometry: ArmGeometry,
    layout: TaskLayout,
    options: ModelOptions,
    scene: SceneOptions | None = None,
    *,
    arm_builder: ArmBuilder | None = None,
) -> mjcf.RootElement:
    """The whole dual-arm scene as an MJCF tree (pure: no simulation state).

    ``arm_builder`` defaults to ``model.arm.build_arm``; tests pass a kinematic stand-in.
    """
    scene = SceneOptions() if scene is None else scene
    plate = layout.plate
    if scene.tools.cutter_length <= plate.thickness + plate.cut_overtravel:
        raise ConfigError(
            "tools.cutter_length",
            f"must exceed plate thickness + cut_overtravel = {plate.thickness + plate.cut_overtravel:g} m "
            f"so the housing stays below the plate (got {scene.tools.cutter_length:g})",
        )
    builder = build_arm if arm_builder is None else arm_builder
    root = mjcf.RootElement(model=SCENE_MODEL)
    apply_simulation_options(root, options)
    root.compiler.autolimits = True
    _add_assets_and_visuals(root, scene)
    _add_environment(root, layout, scene)
    _add_plate(root, layout, scene, options.timestep)
    _add_cameras(root, layout)
    for arm in ARMS:
        _attach_arm(root, arm, geometry, layout, options, scene, builder)
    return root
