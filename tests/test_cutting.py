"""Kerf cutting: cells go only under the running cutter; the sample comes free only at the end.

The grinder rides on a rigid stand-in arm welded to a mocap body, so the cutter follows
the kerf closely and the test isolates the cutting logic from arm control. (The carrier
has a free joint: geoms of a body welded to the world do not collide with the static
plate.)
"""

import numpy as np
import pytest

from continuum_sim import ArmGeometry
from continuum_sim.layout import TaskLayout
from continuum_sim.model.cutting import KerfCutter
from continuum_sim.model.options import ModelOptions
from continuum_sim.model.scene import SAMPLE_WELD, build_scene
from continuum_sim.model.tools import ToolOptions
from model_helpers import carry_with_mocap, compile_root, rigid_arm

import mujoco  # noqa: E402

LAYOUT = TaskLayout()
FEED = 0.025  # m/s
CLEAR = 0.012  # start/end this far outside the plate edges


def mocap_scene():
    geometry = ArmGeometry.default()
    root = build_scene(geometry, LAYOUT, ModelOptions(), arm_builder=rigid_arm)
    carry_with_mocap(root, "left", geometry.length)
    model = compile_root(root)
    return geometry, model


def cut_path() -> tuple[np.ndarray, np.ndarray]:
    """TCP waypoints: in from the front edge at cut depth, along the kerf, out the side."""
    kerf = LAYOUT.plate.kerf_polyline().copy()
    kerf[:, 2] += LAYOUT.plate.cut_overtravel
    points = np.vstack([kerf[0] - [0, CLEAR, 0], kerf, kerf[-1] + [CLEAR, 0, 0]])
    return points, np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])


def along(points, cum, s):
    s = float(np.clip(s, 0.0, cum[-1]))
    i = min(int(np.searchsorted(cum, s, side="right")) - 1, len(points) - 2)
    return points[i] + (s - cum[i]) / (cum[i + 1] - cum[i]) * (points[i + 1] - points[i])


def drive(model, data, cutter, spindle: bool, stop: float | None = None, settle: float = 0.0):
    """Move the cutter along the kerf at FEED up to arc length ``stop``; returns a log."""
    geometry = ArmGeometry.default()
    points, cum = cut_path()
    stop = cum[-1] if stop is None else stop
    offset = np.array([0, 0, geometry.length + geometry.tools.grinder_length])
    mocap = model.body("left_target").mocapid[0]
    free = model.jnt_qposadr[model.body("left/").jntadr[0]]
    data.mocap_pos[mocap] = data.qpos[free : free + 3] = points[0] - offset
    data.ctrl[model.actuator("left/grinder/spindle").id] = ToolOptions().spindle_speed if spindle else 0.0
    mujoco.mj_forward(model, data)
    log = []  # (time, cells remaining, detached, removed cells, cutter xy, sample pos) after every removal
    t_end = stop / FEED + settle
    while data.time < t_end:
        data.mocap_pos[mocap] = along(points, cum, min(FEED * data.time, stop)) - offset
        mujoco.mj_step(model, data)
        removed = cutter.update(spindle)
        if removed:
            xy = data.geom_xpos[model.geom("left/grinder/cutter").id][:2].copy()
            log.append((data.time, cutter.cells_remaining, cutter.detached, removed, xy, data.body("sample").xpos.copy()))
    return log


def fresh_scene():
    """(model, data, cutter, sample rest position) of a new, uncut mocap scene."""
    _, model = mocap_scene()
    data = mujoco.MjData(model)
    cutter = KerfCutter(model, data)
    mujoco.mj_forward(model, data)
    return model, data, cutter, data.body("sample").xpos.copy()


@pytest.fixture(scope="module")
def full_cut():
    model, data, cutter, rest = fresh_scene()
    log = drive(model, data, cutter, spindle=True)
    fall_from = data.time
    while data.time < fall_from + 0.2:
        mujoco.mj_step(model, data)
    return model, data, cutter, log, rest, data.body("sample").xpos.copy()


def test_every_cell_goes_where_the_cutter_is(full_cut):
    model, data, cutter, log, rest, fallen = full_cut
    assert cutter.cells_remaining == 0 and cutter.removed.all()
    # cutter radius + detection shell (+ 0.5 mm: MuJoCo's convex cylinder–box test is not exact)
    reach = LAYOUT.plate.kerf_width / 2 + ToolOptions().cutter_shell + 0.0005
    for _, _, _, removed, xy, _ in log:
        for k in removed:
            g = cutter.cells[k]
            local = data.geom_xmat[g].reshape(3, 3)[:2, :2].T @ (xy - data.geom_xpos[g][:2])
            outside = np.maximum(np.abs(local) - model.geom_size[g, :2], 0.0)
            assert np.linalg.norm(outside) <= reach  # the cutter (plus its shell) touched the box
    # front edge → corner → side edge (a corner cell may go a little early)
    assert np.all(np.diff(cutter.removal_time) > -0.15)
    assert cutter.removal_time[0] < cutter.removal_time[cutter.n_cells // 2] < cutter.removal_time[-1]


def test_sample_detaches_exactly_with_the_last_cell(full_cut):
    model, data, cutter, log, rest, fallen = full_cut
    assert all(not detached for _, remaining, detached, *_ in log if remaining > 0)
    assert log[-1][1] == 0 and log[-1][2]
    assert cutter.detached and cutter.detach_time == pytest.approx(np.nanmax(cutter.removal_time))
    assert data.eq_active[model.equality(SAMPLE_WELD).id] == 0
    # while welded, the sample did not move (the cutter ran along its edges); once free, it falls
    assert max(np.linalg.norm(entry[5] - rest) for entry in log) < 2e-4
    assert rest[2] - fallen[2] > 0.1
    status = cutter.status()
    assert status["detached"] and status["cells_remaining"] == 0 and len(status["cell_removal_times_s"]) == cutter.n_cells


def test_removed_cells_stop_colliding_and_vanish(full_cut):
    model, data, cutter, *_ = full_cut
    assert np.all(model.geom_contype[cutter.cells] == 0) and np.all(model.geom_conaffinity[cutter.cells] == 0)
    assert np.all(model.geom_rgba[cutter.cells, 3] == 0)


def test_reset_restores_cells_and_weld(full_cut):
    model, data, cutter, _ = fresh_scene()  # a fresh model: the fixture's one stays cut for the other tests
    contype = model.geom_contype[cutter.cells].copy()
    drive(model, data, cutter, spindle=True)
    assert cutter.detached
    cutter.reset(reset_data=True)
    assert cutter.cells_remaining == cutter.n_cells and not cutter.detached and data.time == 0
    np.testing.assert_array_equal(model.geom_contype[cutter.cells], contype)
    assert data.eq_active[model.equality(SAMPLE_WELD).id] == 1


def test_partial_cut_keeps_the_sample_attached():
    model, data, cutter, rest = fresh_scene()
    points, cum = cut_path()
    drive(model, data, cutter, spindle=True, stop=cum[-2] - 0.02, settle=0.3)  # stop short of the side edge
    assert 1 <= cutter.cells_remaining < cutter.n_cells // 2
    assert not cutter.detached and data.eq_active[model.equality(SAMPLE_WELD).id] == 1
    assert np.linalg.norm(data.body("sample").xpos - rest) < 2e-4


def test_spindle_off_removes_nothing():
    model, data, cutter, rest = fresh_scene()
    log = drive(model, data, cutter, spindle=False, settle=0.2)
    assert log == [] and cutter.cells_remaining == cutter.n_cells and not cutter.detached
    assert np.linalg.norm(data.body("sample").xpos - rest) < 2e-4


def test_update_without_flag_reads_the_spindle_speed():
    geometry, model = mocap_scene()
    data = mujoco.MjData(model)
    cutter = KerfCutter(model, data)
    points, cum = cut_path()
    offset = np.array([0, 0, geometry.length + geometry.tools.grinder_length])
    mocap = model.body("left_target").mocapid[0]
    free = model.jnt_qposadr[model.body("left/").jntadr[0]]
    data.mocap_pos[mocap] = data.qpos[free : free + 3] = along(points, cum, CLEAR + 0.004) - offset  # in cell 0
    for spin, expect_removed in ((0.0, False), (ToolOptions().spindle_speed, True)):
        data.ctrl[model.actuator("left/grinder/spindle").id] = spin
        for _ in range(100):
            mujoco.mj_step(model, data)
            cutter.update()
        assert cutter.removed[0] == expect_removed
    assert cutter.spindle_speed == pytest.approx(ToolOptions().spindle_speed, rel=0.01)


def test_cutter_requires_a_grinder_scene():
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
    with pytest.raises(ValueError, match="left/grinder/cutter"):
        KerfCutter(model, mujoco.MjData(model))
