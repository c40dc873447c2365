"""Cooperative workspace (SPEC §4): clouds, overlap, section plot, reachability checks."""

import numpy as np
import pytest

from continuum_sim import ConfigError
from continuum_sim import kinematics as kin
from continuum_sim.cli import main
from continuum_sim.layout import TaskLayout
from continuum_sim.toolpath import PlanConfig, grinder_poses, gripper_poses
from continuum_sim.workspace import (
    UnreachableError,
    VoxelSet,
    WorkspaceConfig,
    check_poses,
    compute_workspace,
    plot_workspace,
    sample_configurations,
)
from conftest import random_q


@pytest.fixture(scope="module")
def ws(geometry):
    return compute_workspace(geometry, TaskLayout(), WorkspaceConfig(samples=30_000, voxel=0.02))


def test_clouds_lie_within_reach_and_are_seeded(ws, geometry):
    layout = TaskLayout()
    for arm, pts in (("left", ws.left_points), ("right", ws.right_points)):
        mount = layout.mount(arm)
        reach = geometry.length + geometry.tools.length(mount.tool)
        d = np.linalg.norm(pts - np.array(mount.position), axis=1)
        assert d.max() <= reach + 1e-12 and pts[:, 2].max() > 0.9 * reach
    again = compute_workspace(geometry, layout, WorkspaceConfig(samples=30_000, voxel=0.02))
    np.testing.assert_array_equal(again.left_points, ws.left_points)
    q = sample_configurations(geometry, 1000, 3)
    assert np.all(q[:, 0::2] <= geometry.max_bend) and np.all(q[:, 0::2] >= 0)


def test_overlap_and_volumes(ws):
    s = ws.summary()
    assert 0 < s["overlap_volume_m3"] <= min(s["left_volume_m3"], s["right_volume_m3"])
    # Mirror-image mounts, same arm: the two sampled volumes agree closely.
    assert abs(s["left_volume_m3"] - s["right_volume_m3"]) < 0.05 * s["left_volume_m3"]
    assert ws.overlap.contains(ws.overlap.centres()).all()


def test_contains_reachable_points_and_rejects_far_ones(ws, geometry):
    layout = TaskLayout()
    rng = np.random.default_rng(9)
    q = random_q(rng, geometry, 300)
    pts = kin.tool_centre_pose(geometry, q, "grinder", base=layout.left.base_transform())[:, :3, 3]
    assert ws.left.contains(pts, dilate=1).mean() >= 0.97
    assert not ws.left.contains(np.array([[0.0, 0.0, 2.0], [1.0, 0.0, 0.0]]), dilate=1).any()


def test_task_lies_in_the_cooperative_workspace(ws, geometry):
    """The default task's key positions are inside the sampled clouds and reachable as poses."""
    layout, cfg = TaskLayout(), PlanConfig()
    gp, hp = grinder_poses(layout, cfg), gripper_poses(layout, cfg)
    assert ws.left.contains(np.array([p[:3, 3] for p in gp.values()]), dilate=1).all()
    assert ws.right.contains(np.array([p[:3, 3] for p in hp.values()]), dilate=1).all()
    # The kerf is where both tools can be: inside the overlap.
    assert ws.overlap.contains(layout.plate.kerf_polyline(), dilate=1).all()
    results = check_poses(geometry, layout, "left", list(gp.items()), "axis")
    assert all(r.success for r in results)


def test_check_poses_names_first_unreachable(geometry, ws):
    layout = TaskLayout()
    good = grinder_poses(layout, PlanConfig())["inner_corner"]
    far = good.copy()
    far[:3, 3] = [0.5, 0.5, 0.2]
    with pytest.raises(UnreachableError, match=r"far corner at \(500.0, 500.0, 200.0\) mm .*outside the sampled workspace"):
        check_poses(geometry, layout, "left", [("good", good), ("far corner", far), ("also far", far)], "axis",
                    workspace=ws)


def test_voxelset_basics():
    v = VoxelSet.from_points(np.array([[0.001, 0.001, 0.001], [0.005, 0.002, 0.0], [0.031, 0.0, 0.0]]), 0.01)
    assert len(v.keys) == 2 and np.isclose(v.volume, 2e-6)
    assert v.contains(np.array([[0.009, 0.009, 0.009], [0.015, 0.0, 0.0]])).tolist() == [True, False]
    assert v.contains(np.array([[0.015, 0.0, 0.0]]), dilate=1).tolist() == [True]


def test_config_validation():
    with pytest.raises(ConfigError, match="samples"):
        WorkspaceConfig(samples=5)
    with pytest.raises(ConfigError, match="voxel"):
        WorkspaceConfig(voxel=0.0)
    with pytest.raises(ConfigError, match="point"):
        WorkspaceConfig(point="elbow")


def test_plot_and_cli(ws, tmp_path, capsys):
    plot_workspace(ws, tmp_path / "ws.png", TaskLayout(), {"kerf": TaskLayout().plate.kerf_polyline()})
    assert (tmp_path / "ws.png").stat().st_size > 10_000
    assert main(["workspace", "--out", str(tmp_path / "cli"), "--samples", "20000", "--voxel", "0.02"]) == 0
    out = capsys.readouterr().out
    assert '"task_poses_reachable": true' in out
    assert (tmp_path / "cli" / "workspace.png").exists() and (tmp_path / "cli" / "workspace.json").exists()
