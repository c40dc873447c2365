"""The sample-removal scene and its tools (SPEC §5, §6; issue 4)."""

import mujoco  # noqa: E402  (continuum_sim.model.scene chose the GL backend first)
import numpy as np
import pytest
from model_helpers import carry_with_mocap, compile_root, rigid_arm

from continuum_sim import ArmGeometry, ConfigError
from continuum_sim.kinematics import straight_cable_lengths
from continuum_sim.layout import PlateLayout, TaskLayout
from continuum_sim.model.options import ModelOptions
from continuum_sim.model.scene import (
    CAMERAS,
    KERF_BAND,
    SAMPLE_WELD,
    SceneOptions,
    build_scene,
    look_at,
)
from continuum_sim.model.state import set_arm_configuration
from continuum_sim.model.tools import ToolOptions

LAYOUT = TaskLayout()


@pytest.fixture(scope="module")
def scene():
    """The default scene with the real arms at their straight pose, motors holding it."""
    model = compile_root(build_scene(ArmGeometry.default(), LAYOUT, ModelOptions()))
    data = mujoco.MjData(model)
    hold_straight(model, data, ArmGeometry.default())
    mujoco.mj_forward(model, data)
    return model, data


def hold_straight(model, data, geometry):
    for arm in ("left", "right"):
        for name, length in zip(geometry.cable_names(arm), straight_cable_lengths(geometry)):
            data.ctrl[model.actuator(name).id] = length


def geoms_of(model, prefix):
    return [i for i in range(model.ngeom) if model.geom(i).name.startswith(prefix)]


def test_scene_has_the_spec_names(scene, geometry):
    model, _ = scene
    for arm in ("left", "right"):
        assert model.site(f"{arm}/tcp").id >= 0
        for name in geometry.cable_names(arm):
            assert model.tendon(name).id >= 0 and model.actuator(name).id >= 0
    for camera in CAMERAS:
        assert model.camera(camera).id >= 0
    weld = model.equality(SAMPLE_WELD)
    assert model.eq_type[weld.id] == mujoco.mjtEq.mjEQ_WELD and model.eq_active0[weld.id]
    assert model.body("plate").dofnum == 0 and model.body_weldid[model.body("plate").id] == 0  # static
    assert model.jnt_type[model.body("sample").jntadr[0]] == mujoco.mjtJoint.mjJNT_FREE
    assert [model.geom(n).id >= 0 for n in KERF_BAND] == [True, True]


def test_spindle_and_gripper_actuators(scene):
    model, _ = scene
    spindle = model.actuator("left/grinder/spindle")
    assert model.actuator_trntype[spindle.id] == mujoco.mjtTrn.mjTRN_JOINT
    assert model.joint(model.actuator_trnid[spindle.id, 0]).name == "left/grinder/spindle"
    assert model.actuator_biasprm[spindle.id, 2] < 0 and model.actuator_biasprm[spindle.id, 1] == 0  # velocity servo
    axis = model.jnt_axis[model.joint("left/grinder/spindle").id]
    np.testing.assert_allclose(axis, [0, 0, 1])
    cable = model.actuator("right/gripper/cable")
    assert model.actuator_trntype[cable.id] == mujoco.mjtTrn.mjTRN_TENDON
    assert model.actuator_forcerange[cable.id, 1] == 0.0 and model.actuator_forcerange[cable.id, 0] < 0  # pulls only


def test_tool_centre_points_match_the_tools(geometry):
    """``<arm>/tcp`` (planner) sits on the cutter's tip face centre and between the pads."""
    model = compile_root(build_scene(geometry, LAYOUT, ModelOptions()))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    for _ in range(3):
        for arm in ("left", "right"):
            q = np.concatenate([[rng.uniform(0, 1.2), rng.uniform(-np.pi, np.pi)] for _ in range(3)])
            set_arm_configuration(model, data, geometry, arm, q)
        mujoco.mj_forward(model, data)
        cutter = model.geom("left/grinder/cutter")
        axis = data.geom_xmat[cutter.id].reshape(3, 3)[:, 2]
        tip_face = data.geom_xpos[cutter.id] + model.geom_size[cutter.id, 1] * axis
        np.testing.assert_allclose(tip_face, data.site("left/tcp").xpos, atol=1e-9)
        assert model.geom_size[cutter.id, 0] * 2 == pytest.approx(LAYOUT.plate.kerf_width)
        # Gripping-face centres: half a pad thickness from each pad's centre, toward the other.
        tcp_frame = data.site_xmat[model.site("right/tcp").id].reshape(3, 3)
        faces, normals = [], []
        for side, sign in (("a", 1.0), ("b", -1.0)):
            pad = model.geom(f"right/gripper/pad_{side}").id
            normal = data.geom_xmat[pad].reshape(3, 3)[:, 0]
            faces.append(data.geom_xpos[pad] - sign * model.geom_size[pad, 0] * normal)
            normals.append(normal)
        np.testing.assert_allclose((faces[0] + faces[1]) / 2, data.site("right/tcp").xpos, atol=1e-9)
        across = (faces[0] - faces[1]) / np.linalg.norm(faces[0] - faces[1])
        assert abs(across @ tcp_frame[:, 0]) == pytest.approx(1.0)  # jaws close along the tool x axis
        # Pad faces turned by the grasp tilt about tool y: flat on the plate at the planned grasp.
        plate_normal_in_tool = LAYOUT.grasp.rotation().T @ [0.0, 0.0, 1.0]
        for normal in normals:
            np.testing.assert_allclose(abs(tcp_frame.T @ normal @ plate_normal_in_tool), 1.0, atol=1e-9)


def test_tool_masses(scene):
    model, _ = scene
    options = ModelOptions()
    for tool, mass in (("left/grinder/", options.grinder_mass), ("right/gripper/", options.gripper_mass)):
        bodies = [i for i in range(model.nbody) if model.body(i).name.startswith(tool)]
        assert model.body_mass[bodies].sum() == pytest.approx(mass)


def test_straight_arms_clear_the_plate(scene):
    """At the straight pose nothing of either arm or tool touches the plate, sample or each other."""
    model, data = scene
    assert not [c for c in data.contact[: data.ncon] if c.dist < 0]
    robot = geoms_of(model, "left/") + geoms_of(model, "right/")
    world = [model.geom(n).id for n in ("plate_main", "plate_side", "sample", "clamp_post", "clamp_upper")]
    fromto = np.zeros(6)
    gap = min(mujoco.mj_geomDistance(model, data, r, w, 0.05, fromto) for r in robot for w in world)
    assert gap > 0.003


def test_cutter_collides_with_nothing_and_the_housing_not_with_its_own_arm(scene):
    """The cutter meets the foam as voxels (cutting.FoamCutter), never as contacts."""
    model, _ = scene
    cutter = model.geom("left/grinder/cutter").id
    assert model.geom_contype[cutter] == 0 and model.geom_conaffinity[cutter] == 0
    housing = model.geom("left/grinder/housing").id
    for g in geoms_of(model, "left/"):
        collides = (model.geom_contype[housing] & model.geom_conaffinity[g]) or (
            model.geom_contype[g] & model.geom_conaffinity[housing]
        )
        assert not collides, model.geom(g).name
    for name in ("plate_main", "sample", "right/gripper/pad_a"):  # … but with these
        g = model.geom(name).id
        assert (model.geom_contype[housing] & model.geom_conaffinity[g]) or (model.geom_contype[g] & model.geom_conaffinity[housing])


def test_plate_pieces_tile_the_plate(scene):
    """Plate boxes + kerf band (visual) + sample (+ its clearance) cover the plate exactly once."""
    model, data = scene
    plate = LAYOUT.plate
    gap = SceneOptions().sample_gap
    pieces = ["plate_main", "plate_side", "sample", *KERF_BAND]
    area = sum(4 * model.geom_size[model.geom(n).id, 0] * model.geom_size[model.geom(n).id, 1] for n in pieces)
    clearance = gap * (plate.sample_x - gap) + gap * plate.sample_y
    assert area + clearance == pytest.approx(plate.size[0] * plate.size[1], rel=1e-9)
    for n in pieces:
        assert 2 * model.geom_size[model.geom(n).id, 2] == pytest.approx(plate.thickness)
    # the kerf band boxes lie along the kerf centre line (their centres within half a kerf width)
    line = plate.kerf_polyline()
    for n in KERF_BAND:
        g = model.geom(n).id
        c = data.geom_xpos[g][:2]
        d = min(_point_segment_distance(c, line[i, :2], line[i + 1, :2]) for i in range(len(line) - 1))
        assert d < 1e-9 + plate.kerf_width / 2
        assert model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0  # shown only: the voxels are the material
    # the foam contacts are the layout's soft ones
    for n in ("plate_main", "plate_side", "sample"):
        np.testing.assert_allclose(model.geom_solref[model.geom(n).id], plate.contact_solref)
        np.testing.assert_allclose(model.geom_solimp[model.geom(n).id, :3], plate.contact_solimp)


def _point_segment_distance(p, a, b):
    t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * (b - a))))


def test_sample_weld_holds_then_releases(geometry):
    model = compile_root(build_scene(geometry, LAYOUT, ModelOptions(segments_per_section=3)))
    data = mujoco.MjData(model)
    hold_straight(model, data, _resampled(geometry, 3))
    mujoco.mj_forward(model, data)
    start = data.body("sample").xpos.copy()
    while data.time < 0.3:
        mujoco.mj_step(model, data)
    assert np.linalg.norm(data.body("sample").xpos - start) < 1e-4
    data.eq_active[model.equality(SAMPLE_WELD).id] = 0
    while data.time < 0.5:
        mujoco.mj_step(model, data)
    assert start[2] - data.body("sample").xpos[2] > 0.1  # falls freely once released


def _resampled(geometry, n):
    from continuum_sim.model.options import model_geometry

    return model_geometry(geometry, ModelOptions(segments_per_section=n))


def test_spindle_runs_at_commanded_speed(geometry):
    options = ModelOptions(segments_per_section=2)
    model = compile_root(build_scene(geometry, LAYOUT, options))
    data = mujoco.MjData(model)
    hold_straight(model, data, _resampled(geometry, 2))
    speed = ToolOptions().spindle_speed
    data.ctrl[model.actuator("left/grinder/spindle").id] = speed
    dof = model.jnt_dofadr[model.joint("left/grinder/spindle").id]
    while data.time < 0.1:
        mujoco.mj_step(model, data)
    # spin-up at the torque limit: ω = τ_max·t / J (rotor armature + the spinning parts' axial inertia)
    body = model.body("left/grinder/spindle").id
    inertia = model.dof_armature[dof] + model.body_inertia[body].min()  # a slender cylinder: smallest about its axis
    assert data.qvel[dof] == pytest.approx(ToolOptions().spindle_max_torque * data.time / inertia, rel=0.03)
    while data.time < 0.7:
        mujoco.mj_step(model, data)
    assert data.qvel[dof] == pytest.approx(speed, rel=0.01)
    assert not any(w.number for w in data.warning)


def carried_gripper_scene(pad_friction: float = 1.0):
    """The default scene, the right arm replaced by a rigid carrier welded to a mocap body.

    The pads' contact wins over the foam's (priority), so their friction is the grasp's.
    """
    geometry = ArmGeometry.default()
    scene = SceneOptions(tools=ToolOptions(pad_friction=pad_friction))
    root = build_scene(geometry, LAYOUT, ModelOptions(), scene, arm_builder=rigid_arm)
    carry_with_mocap(root, "right", geometry.length)
    return geometry, compile_root(root)


@pytest.fixture(scope="module")
def carried_gripper():
    return carried_gripper_scene()


def test_gripper_springs_open_and_cable_closes(carried_gripper):
    geometry, model = carried_gripper
    data = mujoco.MjData(model)
    tools = ToolOptions()
    cable = model.actuator("right/gripper/cable").id
    jaws = [model.jnt_qposadr[model.joint(f"right/gripper/jaw_{s}").id] for s in "ab"]
    data.qpos[jaws] = 0.008
    data.ctrl[cable] = tools.gripper_cable_open
    while data.time < 0.5:
        mujoco.mj_step(model, data)
    np.testing.assert_allclose(data.qpos[jaws], 0.0, atol=2e-4)  # preloaded springs hold the jaws on their open stops
    jaw_joints = {model.joint(f"right/gripper/jaw_{s}").id for s in "ab"}
    limits = [i for i in range(data.nefc) if data.efc_type[i] == mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT]
    assert any(data.efc_id[i] in jaw_joints for i in limits)  # on the stops, pressed by the preload
    data.ctrl[cable] = tools.gripper_cable_for_gap(0.012)
    while data.time < 1.5:
        mujoco.mj_step(model, data)
    gap = tools.gripper_open_gap - data.qpos[jaws].sum()
    # The bare cable servo (no motor loop here) stands off by the springs' load over its gain.
    spring_load = tools.gripper_preload + tools.gripper_spring * data.qpos[jaws].mean()
    assert gap == pytest.approx(0.012 + spring_load / tools.gripper_kp, abs=0.0003)  # one tension on both jaws


@pytest.mark.parametrize("friction", [1.0, 0.0])
def test_gripper_holds_and_carries_the_sample(friction):
    """Jaws closed across the plate thickness hold the released foam sample while moving
    (pulled back along the tool axis: friction does it; without friction it stays behind)."""
    geometry, model = carried_gripper_scene(friction)
    data = mujoco.MjData(model)
    tools = ToolOptions()
    plate = LAYOUT.plate
    mocap = model.body("right_target").mocapid[0]
    free = model.jnt_qposadr[model.body("right/").jntadr[0]]
    # The task's grasp: tool z into the side edge, tilted as the layout says (the pads are
    # turned to lie flat on the plate at that tilt); the jaws close across the thickness.
    rot = LAYOUT.grasp.rotation()
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rot.ravel())
    reach = rot @ [0, 0, geometry.length + geometry.tools.gripper_length]
    tcp_goal = np.array([plate.corner_x - LAYOUT.grasp.depth, plate.sample_centre[1], plate.sample_centre[2]])
    base_goal = tcp_goal - reach

    def base_at(t: float) -> np.ndarray:  # approach along the tool axis, then grip, then carry
        s = np.clip(t / 0.4, 0.0, 1.0)
        approach = base_goal - (1 - s * s * (3 - 2 * s)) * 0.05 * rot[:, 2]
        c = np.clip((t - 1.0) / 1.0, 0.0, 1.0)
        return approach + c * c * (3 - 2 * c) * np.array([0.10, -0.06, 0.06])

    data.qpos[free : free + 3] = base_at(0.0)
    data.qpos[free + 3 : free + 7] = quat
    data.mocap_pos[mocap], data.mocap_quat[mocap] = base_at(0.0), quat
    mujoco.mj_forward(model, data)
    cable = model.actuator("right/gripper/cable").id
    while data.time < 2.3:
        data.mocap_pos[mocap] = base_at(data.time)
        if data.time >= 0.5:
            data.ctrl[cable] = tools.gripper_cable_closed
        if data.time >= 0.9:
            data.eq_active[model.equality(SAMPLE_WELD).id] = 0  # as if the kerf were cut
        mujoco.mj_step(model, data)
        if abs(data.time - 0.99) < 5e-4:  # released and settled in the jaws, not yet carried
            held = data.body("sample").xpos - data.site("right/tcp").xpos
    carried = data.body("sample").xpos - data.site("right/tcp").xpos
    if friction == 0.0:
        assert np.linalg.norm(carried - held) > 0.02
        return
    assert np.linalg.norm(carried - held) < 0.002
    assert data.body("sample").xpos[2] > plate.sample_centre[2] + 0.05  # lifted with the gripper
    force = data.actuator_force[cable]
    assert force == pytest.approx(-tools.gripper_max_force)  # closed on an object: the loop saturates
    assert not any(w.number for w in data.warning)


def test_look_at_points_the_camera_at_the_target():
    pos, target = np.array([0.3, -0.8, 0.6]), np.array([0.0, 0.05, 0.3])
    x, y = np.array(look_at(pos, target)[:3]), np.array(look_at(pos, target)[3:])
    forward = -np.cross(x, y)  # MuJoCo cameras look along their −z
    np.testing.assert_allclose(forward, (target - pos) / np.linalg.norm(target - pos), atol=1e-12)
    assert y[2] > 0  # upright


def test_cameras_see_the_cut(scene):
    model, _ = scene
    data = mujoco.MjData(model)  # the initial state: the close-up rides with the sample, which other tests move
    mujoco.mj_forward(model, data)
    kerf = LAYOUT.plate.kerf_polyline()
    centre = kerf.mean(axis=0)
    cam = model.camera("closeup").id
    view = -data.cam_xmat[cam].reshape(3, 3)[:, 2]
    for p, limit in ((centre, 5.0), *((q, model.cam_fovy[cam] / 2) for q in kerf)):  # aimed at the kerf; all of it in view
        to_p = p - data.cam_xpos[cam]
        assert np.degrees(np.arccos(view @ to_p / np.linalg.norm(to_p))) < limit
    # The overview is framed on the work (docs/video.md): the plate's corners, the kerf and both
    # arms 15 cm below the plate (their upper sections) inside the 4:3 frame.
    cam = model.camera("overview").id
    plate = LAYOUT.plate
    x0, y0 = plate.corner_x - plate.size[0], plate.corner_y
    corners = [np.array([x, y, plate.top_z]) for x in (x0, plate.corner_x) for y in (y0, y0 + plate.size[1])]
    arms = [np.array(m.position) + [0, 0, plate.top_z - 0.15] for m in (LAYOUT.left, LAYOUT.right)]
    tan_v = np.tan(np.radians(model.cam_fovy[cam]) / 2)
    for p in (*corners, *arms, centre):
        local = (p - data.cam_xpos[cam]) @ data.cam_xmat[cam].reshape(3, 3)  # x right, y up, −z forward
        assert local[2] < 0 and abs(local[1] / local[2]) < tan_v and abs(local[0] / local[2]) < tan_v * 4 / 3


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: SceneOptions(sample_gap=-1.0), "sample_gap"),
        (lambda: SceneOptions(render_width=3), "render_width"),
        (lambda: ToolOptions(gripper_jaw_travel=0.02), "gripper_jaw_travel"),
        (lambda: ToolOptions(spindle_speed=5000.0), "spindle_speed"),
        (lambda: ToolOptions(pad_solref=(0.0, 1.0)), "pad_solref[0]"),
        (lambda: ToolOptions(pad_solimp=(0.99, 0.9, 0.001)), "pad_solimp[1]"),
        (lambda: ToolOptions(gripper_cable_speed=0.0), "gripper_cable_speed"),
        (lambda: PlateLayout(contact_solimp=(0.9, 1.2, 0.002)), "contact_solimp[1]"),
        (
            lambda: build_scene(ArmGeometry(), LAYOUT, ModelOptions(), SceneOptions(tools=ToolOptions(cutter_length=0.011))),
            "tools.cutter_length",
        ),
        (
            lambda: build_scene(
                ArmGeometry(), TaskLayout(plate=PlateLayout(sample_x=0.15)), ModelOptions(), arm_builder=rigid_arm
            ),
            "plate.sample_x",
        ),
    ],
)
def test_invalid_scene_config_names_the_field(make, field):
    with pytest.raises(ConfigError) as info:
        make()
    assert info.value.field == field


def test_a_preload_the_gripper_cable_cannot_beat_is_refused():
    """The jaws' opening preload plus the spring at full travel must stay below the cable's
    force rating, or the gripper never closes: refused with the field and its bound."""
    from continuum_sim.configio import ConfigError
    from continuum_sim.model.scene_options import ToolOptions

    with pytest.raises(ConfigError, match="gripper_preload: must satisfy .* < gripper_max_force"):
        ToolOptions(gripper_preload=2.0)
    assert ToolOptions(gripper_preload=1.5).gripper_preload == 1.5
