"""Task toolpaths and the timed dual-arm plan (SPEC §5)."""

import json
import math

import numpy as np
import pytest

from continuum_sim import ArmGeometry, ConfigError
from continuum_sim import kinematics as kin
from continuum_sim.cli import main
from continuum_sim.ik import StepLimits, step_violations
from continuum_sim.layout import GraspLayout, PlateLayout, TaskLayout
from continuum_sim.toolpath import (
    STAGE_NAMES,
    PlanConfig,
    arm_clearance,
    arm_envelope,
    grinder_poses,
    plan_task,
    plate_clearance,
    sample_box_gaps,
    save_plan,
    solve_planar_demo,
    trapezoid_duration,
    trapezoid_position,
)
from continuum_sim.workspace import UnreachableError


@pytest.fixture(scope="module")
def layout():
    return TaskLayout()


@pytest.fixture(scope="module")
def cfg():
    return PlanConfig()


@pytest.fixture(scope="module")
def plan(geometry, layout, cfg):
    return plan_task(geometry, layout, cfg)


def test_plan_arrays_and_stages(plan, cfg):
    n = plan.n
    assert plan.q_left.shape == plan.q_right.shape == (n, 6)
    assert plan.tcp_left.shape == plan.tcp_right.shape == (n, 4, 4)
    for a in (plan.stage, plan.segment, plan.gripper_closed, plan.spindle_on, plan.cutting):
        assert a.shape == (n,)
    np.testing.assert_allclose(np.diff(plan.t), 1.0 / cfg.sample_rate_hz, atol=1e-9)
    assert plan.stage_names == STAGE_NAMES == ("initial", "clamping", "milling", "retrieval", "return")
    assert np.all(np.diff(plan.stage) >= 0) and set(plan.stage.tolist()) == {0, 1, 2, 3, 4}
    # Starts and ends at the initial configuration (straight arms by default).
    np.testing.assert_allclose(kin.to_bending(plan.q_left[0]), 0.0, atol=1e-15)
    np.testing.assert_allclose(kin.to_bending(plan.q_left[-1]), 0.0, atol=1e-12)
    np.testing.assert_allclose(kin.to_bending(plan.q_right[0]), 0.0, atol=1e-15)


def test_tool_flags_follow_the_stages(plan):
    milling = plan.stage_mask("milling")
    assert plan.spindle_on[milling].any() and not plan.spindle_on[~milling].any()
    assert plan.cutting.any() and np.all(milling[plan.cutting]) and np.all(plan.spindle_on[plan.cutting])
    closed = np.flatnonzero(plan.gripper_closed)
    assert closed.size and np.all(plan.gripper_closed[closed[0]:])  # closes once, never reopens
    assert plan.t[closed[0]] < plan.t[plan.stage_mask("milling")][0]  # holds the plate before the cut
    assert np.all(plan.gripper_closed[plan.stage_mask("retrieval")])


def test_planned_poses_are_fk_of_planned_shapes(plan, geometry, layout):
    idx = np.arange(0, plan.n, 97)
    for arm, q, tcp in (("left", plan.q_left, plan.tcp_left), ("right", plan.q_right, plan.tcp_right)):
        mount = layout.mount(arm)
        fk = kin.tool_centre_pose(geometry, q[idx], mount.tool, base=mount.base_transform())
        np.testing.assert_allclose(fk, tcp[idx], atol=1e-12)


def test_cut_follows_kerf_with_vertical_spindle(plan, layout, cfg):
    cut = plan.tcp_left[plan.cutting]
    plate = layout.plate
    np.testing.assert_allclose(cut[:, 2, 3], plate.top_z + plate.cut_overtravel, atol=1e-4)  # through the plate
    assert plan.metrics["cut_path_max_deviation_m"] < 1e-4  # eq. 12 interpolation between 2 mm waypoints
    tilt = np.degrees(np.arccos(np.clip(cut[:, 2, 2], -1, 1)))
    assert tilt.max() < 0.05  # spindle normal to the plate
    kerf = plate.kerf_polyline()
    np.testing.assert_allclose(cut[-1, :2, 3], kerf[-1, :2], atol=1e-9)  # the cut ends through the side edge
    assert cut[0, 1, 3] < plate.corner_y - plate.kerf_width / 2  # and starts outside the front edge
    # Feed: slow on the cut, fast elsewhere.
    speed = np.linalg.norm(np.diff(plan.tcp_left[:, :3, 3], axis=0), axis=1) * cfg.sample_rate_hz
    cutting = plan.cutting[1:] & plan.cutting[:-1]
    assert speed[cutting].max() <= cfg.cut_speed * 1.05
    assert abs(np.median(speed[cutting]) - cfg.cut_speed) < 1e-4
    moving = speed > cfg.cut_speed * 1.5
    assert moving.any() and speed.max() <= cfg.fast_speed * 1.6  # joint transfers are not Cartesian-exact


def test_gripper_holds_still_while_milling(plan, layout):
    held = plan.tcp_right[plan.stage_mask("milling")]
    np.testing.assert_allclose(held, np.broadcast_to(layout.grasp_pose(), held.shape), atol=1e-9)
    carried = plan.tcp_right[-1, :3, 3] - layout.grasp_pose()[:3, 3]
    np.testing.assert_allclose(carried, PlanConfig().carry_offset, atol=1e-9)


def test_step_limits_on_task_paths(plan, cfg):
    limits = cfg.limits
    for name, wp in plan.waypoints.items():
        q = wp["q"]
        assert np.all(wp["position_error"] <= 1e-9) and np.all(wp["orientation_error"] <= 1e-9), name
        for a, b in zip(q[:-1], q[1:]):
            assert not step_violations(a, b, limits), name
    # The 100 Hz samples move far less per step than the limits.
    for arm in ("left", "right"):
        steps = plan.metrics["step_limits"][arm]
        assert steps["max_dtheta_deg_per_sample"] < limits.max_dtheta_deg
        assert steps["max_dphi_deg_per_sample_bent"] < limits.max_dphi_deg


def test_arms_never_collide(plan, geometry, layout, cfg):
    clearance = arm_clearance(geometry, layout, cfg, plan.q_left, plan.q_right)
    # The matmul form of the pairwise distances against the plain difference, on some samples.
    from continuum_sim.toolpath import arm_envelope

    pl, rl = arm_envelope(geometry, layout, cfg, "left", plan.q_left[::97])
    pr, rr = arm_envelope(geometry, layout, cfg, "right", plan.q_right[::97])
    direct = np.min(np.linalg.norm(pl[:, :, None] - pr[:, None], axis=-1) - rl[:, None] - rr[None], axis=(1, 2))
    np.testing.assert_allclose(clearance[::97], direct, atol=1e-9)
    assert clearance.min() > 0.005
    assert math.isclose(clearance.min(), plan.metrics["min_arm_clearance_m"], abs_tol=1e-12)
    assert plan.metrics["min_plate_clearance_left_m"] > 0.005
    assert plan.metrics["min_plate_clearance_right_m"] > 0.005


def test_straight_arms_clear_the_plate(geometry, layout):
    for arm in ("left", "right"):
        assert plate_clearance(geometry, layout, np.zeros((1, 6)), arm)[0] > 0.005


def test_planar_mode_keeps_phase_in_plane(geometry, layout, cfg):
    demo = solve_planar_demo(geometry, layout, cfg)
    for phase, sol in demo.items():
        assert sol.success, sol.message
        assert np.all(sol.position_error <= 1e-9)
        for a, b in zip(sol.q[:-1], sol.q[1:]):
            assert not step_violations(a, b, cfg.limits)
    phases = demo["planar"].q[:, 1::2]
    assert np.all(np.isclose(phases, 0.0, atol=1e-15) | np.isclose(np.abs(phases), np.pi, atol=1e-15))


def test_plan_is_deterministic(plan, geometry, layout, cfg):
    again = plan_task(geometry, layout, cfg)
    np.testing.assert_array_equal(again.q_left, plan.q_left)
    np.testing.assert_array_equal(again.q_right, plan.q_right)


def test_unreachable_layout_is_refused_naming_the_point(geometry):
    low = TaskLayout(plate=PlateLayout(top_z=0.30))
    with pytest.raises(UnreachableError, match=r"grinder pre cut at .* outside the left arm's workspace"):
        plan_task(geometry, low)
    assert issubclass(UnreachableError, ConfigError)  # the CLI maps it to exit code 2
    with pytest.raises(UnreachableError, match="gripper pre grasp at .* right arm"):
        plan_task(geometry, TaskLayout(grasp=GraspLayout(tilt_deg=0.0)))
    # Planar phase mode cannot reach the off-plane kerf: refused with the first point named.
    with pytest.raises(UnreachableError, match="grinder pre cut"):
        plan_task(geometry, TaskLayout(), PlanConfig(grinder_phase="planar"))


def test_collision_margin_is_enforced(geometry, layout):
    with pytest.raises(UnreachableError, match="arms come within"):
        plan_task(geometry, layout, PlanConfig(min_clearance=0.2))


def test_carried_sample_is_kept_clear_of_the_grinder(plan, geometry, layout, cfg):
    assert plan.metrics["min_sample_clearance_m"] >= cfg.min_clearance
    assert plan.metrics["min_sample_clearance_stage"].startswith(("retrieval", "return"))
    # Carried straight sideways at the plate's height, the sample runs into the waiting grinder.
    with pytest.raises(UnreachableError, match="plan.carry_offset: the carried sample comes within"):
        plan_task(geometry, layout, PlanConfig(carry_offset=(0.0, -0.09, 0.0)))


def test_sample_box_gap_is_the_exact_sphere_to_box_distance(geometry, layout, cfg):
    """With the gripper at the grasp, the sample box is where the layout puts it."""
    q = np.zeros((1, 6))
    pl, rl = arm_envelope(geometry, layout, cfg, "left", q)
    plate = layout.plate
    lo = np.array([plate.corner_x - plate.sample_x, plate.corner_y, plate.top_z - plate.thickness])
    hi = np.array([plate.corner_x, plate.corner_y + plate.sample_y, plate.top_z])
    expected = np.min(np.linalg.norm(np.maximum(np.maximum(lo - pl[0], pl[0] - hi), 0.0), axis=-1) - rl)
    got = sample_box_gaps(geometry, layout, cfg, q, layout.grasp_pose()[None])
    assert got[0] == pytest.approx(expected, abs=1e-12)


def test_plan_config_validation():
    with pytest.raises(ConfigError, match="cut_speed"):
        PlanConfig(cut_speed=0.0)
    with pytest.raises(ConfigError, match="q_left_initial_deg"):
        PlanConfig(q_left_initial_deg=(0.0, 0.0))
    with pytest.raises(ConfigError, match=r"q_right_initial_deg\[2\]"):
        PlanConfig(q_right_initial_deg=(0, 0, 120, 0, 0, 0))
    with pytest.raises(ConfigError, match="grinder_phase"):
        PlanConfig(grinder_phase="spiral")
    with pytest.raises(ConfigError, match="max_dtheta_deg"):
        StepLimits(max_dtheta_deg=-1)
    with pytest.raises(ConfigError, match="grasp.edge_offset"):
        TaskLayout(grasp=GraspLayout(edge_offset=0.06))


def test_trapezoid_profile():
    for d, v, a in ((0.1, 0.04, 0.2), (0.001, 0.04, 0.2)):  # cruise phase, and a triangle
        T = trapezoid_duration(d, v, a)
        t = np.linspace(0, T, 2001)
        s = trapezoid_position(t, d, v, a)
        assert s[0] == 0.0 and math.isclose(s[-1], d, rel_tol=1e-12)
        speed = np.diff(s) / np.diff(t)
        assert np.all(np.diff(s) >= -1e-15) and speed.max() <= v * (1 + 1e-3)
        assert np.abs(np.diff(speed) / np.diff(t)[1:]).max() <= a * 1.05
    assert trapezoid_duration(0.0, 1.0, 1.0) == 0.0


def test_grinder_key_poses_are_ordered(layout, cfg):
    gp = grinder_poses(layout, cfg)
    kerf = layout.plate.kerf_polyline()
    np.testing.assert_allclose(gp["inner_corner"][:2, 3], kerf[1, :2])
    assert gp["pre_cut"][1, 3] < gp["cut_start"][1, 3] < gp["front_edge"][1, 3]
    assert gp["cut_end"][0, 3] > layout.plate.corner_x + layout.plate.kerf_width / 2


def test_save_plan_round_trip(plan, tmp_path):
    save_plan(plan, tmp_path / "plan.npz")
    data = np.load(tmp_path / "plan.npz")
    np.testing.assert_array_equal(data["q_left"], plan.q_left)
    assert tuple(data["stage_names"]) == plan.stage_names
    assert json.loads(str(data["metrics"]))["samples"] == plan.n


# ---------------------------------------------------------------------------- CLI
def test_cli_ik_json(capsys):
    q = np.array([0.5, 0.3, 0.4, -1.0, 0.2, 2.0])
    T = kin.forward_kinematics(ArmGeometry.default(), q)
    assert main(["ik", "--matrix", json.dumps(T.tolist())]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["success"] and out["position_error_m"] <= 1e-9
    assert main(["ik", "--position", "0", "0", "0.9"]) == 1  # unreachable: JSON plus a message
    captured = capsys.readouterr()
    assert json.loads(captured.out)["success"] is False and "outside the workspace" in captured.err
    assert main(["ik", "--matrix", json.dumps(np.full((4, 4), np.nan).tolist())]) == 2
    assert "NaN" in capsys.readouterr().err
    assert main(["ik", "--position", "0", "0", "0.5", "--zaxis", "0", "0", "0"]) == 2


def test_cli_ik_world_frame_axis_mode(capsys, layout):
    p = grinder_poses(layout, PlanConfig())["inner_corner"][:3, 3]
    code = main(["ik", "--arm", "left", "--orientation", "axis", "--position", *map(str, p), "--zaxis", "0", "0", "1"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["frame"] == "world" and out["tool"] == "grinder"
    np.testing.assert_allclose(np.array(out["achieved_pose"])[:3, 3], p, atol=1e-9)


def test_cli_plan_writes_outputs(tmp_path, capsys):
    assert main(["plan", "--out", str(tmp_path), "--no-plots"]) == 0
    assert (tmp_path / "plan.npz").exists() and (tmp_path / "plan_report.json").exists()
    assert "min arm clearance" in capsys.readouterr().out
    bad = tmp_path / "layout.toml"
    bad.write_text("[plate]\ntop_z = 0.3\n")
    assert main(["plan", "--out", str(tmp_path / "x"), "--layout", str(bad), "--no-plots"]) == 2
    assert "outside the left arm's workspace" in capsys.readouterr().err


def test_layout_and_plan_config_toml_round_trip(tmp_path):
    from continuum_sim.configio import from_dict, load_toml, save_toml

    layout = TaskLayout(grasp=GraspLayout(tilt_deg=25.0, depth=0.01))
    cfg = PlanConfig(cut_speed=0.004, limits=StepLimits(max_dtheta_deg=2.0), carry_offset=(0.01, 0.0, -0.02))
    save_toml(layout, tmp_path / "layout.toml")
    save_toml(cfg, tmp_path / "plan.toml")
    assert from_dict(TaskLayout, load_toml(tmp_path / "layout.toml")) == layout
    assert from_dict(PlanConfig, load_toml(tmp_path / "plan.toml")) == cfg
    with pytest.raises(ConfigError, match="grasp.tilt_deg"):
        from_dict(TaskLayout, {"grasp": {"tilt_deg": 90.0}})
