"""The cut is visible in the default run's video (issue 25): the kerf drawn from the cutter's voxels,
the close-up riding with the sample, the overlay, the overview framed on the plate."""

from __future__ import annotations

import numpy as np
import pytest

from continuum_sim.glbackend import choose_gl_backend

choose_gl_backend()
import mujoco  # noqa: E402

from continuum_sim.plant.foam import FoamGrid  # noqa: E402
from continuum_sim.scenario.config import ScenarioConfig  # noqa: E402
from continuum_sim.scenario.runner import build_scene_model  # noqa: E402
from continuum_sim.video_foam import KerfVoxels, kerf_region, project_points  # noqa: E402
from continuum_sim.video_overlay import OverlayValues, draw_overlay, overlay_lines  # noqa: E402

# The old video (7a4d7dd: the band drawn as two static boxes) measured 3.5 (of 255) on the same
# two frames of its close-up (its own camera, same region); the voxel kerf 93 (docs/video.md,
# `python scripts/kerf_visibility.py RUN_DIR` on a `run --video` folder of each commit).
KERF_CHANGE_MIN = 25.0


def test_closeup_shows_the_kerf_being_cut(default_run):
    """Between 12 s (plunged, no column cleared) and 36 s (most of the kerf cleared), the default
    run's close-up pixels over the planned kerf change: the cut shows as it goes, not only at detachment."""
    import imageio.v2 as imageio

    _, metrics, video = default_run  # close-up frames every CLOSEUP_EVERY_S = 12 s (conftest.py)
    reader = imageio.get_reader(video)
    frames = np.array([f for f in reader], dtype=float)
    reader.close()
    config = ScenarioConfig.default()
    w, h = config.simulation.video_width, config.simulation.video_height
    assert frames.shape == (5, h, w, 3)  # 0, 12, 24, 36, 48 s
    _, model = build_scene_model(config)
    plate = config.layout.plate
    region = kerf_region(model, "closeup", plate.kerf_polyline(), plate.kerf_width, w, h)
    assert region.mean() > 0.02  # the kerf is in view and not a sliver
    change = np.abs(frames[3] - frames[1]).mean(axis=2)[region].mean()
    assert change > KERF_CHANGE_MIN, f"kerf region mean change {change:.1f} (of 255)"
    assert metrics["sample_detached"] and not metrics["detached_before_cut_complete"]


def test_kerf_voxels_draw_what_is_left_of_the_band():
    """The band's voxels as merged boxes: the uncut band is its two legs; a cleared stretch
    leaves a gap of exactly the cleared voxels; volumes match the voxel count."""
    config = ScenarioConfig.default()
    _, model = build_scene_model(config)
    plate = config.layout.plate
    lo = np.array([plate.corner_x - 0.1, plate.corner_y, plate.top_z - plate.thickness])
    grid = FoamGrid(lo, np.array([plate.corner_x, plate.corner_y + plate.size[1], plate.top_z]), 0.001)
    kerf = KerfVoxels.from_model(model, grid)
    assert kerf is not None
    full = kerf.boxes(kerf.snapshot(grid.material))
    assert len(full) <= 3  # two legs (a third box where their voxel edges do not line up)
    n_voxels = int(kerf.columns.sum()) * grid.shape[2]
    assert np.prod(2 * full[:, 3:], axis=1).sum() == pytest.approx(n_voxels * grid.voxel_volume, rel=1e-9)
    i0, _, j0, _ = kerf.window
    grid.material[i0 + 2:i0 + 5, j0 + 3:j0 + 9, 4:] = False  # a slot, top layers only
    assert np.array_equal(kerf.unpack(kerf.snapshot(grid.material)),
                          grid.material[i0:kerf.window[1], j0:kerf.window[3]] & kerf.columns[..., None])
    cut = kerf.boxes(kerf.snapshot(grid.material))
    removed = int((~grid.material[i0:kerf.window[1], j0:kerf.window[3]] & kerf.columns[..., None]).sum())
    assert np.prod(2 * cut[:, 3:], axis=1).sum() == pytest.approx((n_voxels - removed) * grid.voxel_volume, rel=1e-9)
    # No box reaches into the slot.
    slot_lo = grid.lo + grid.h * np.array([i0 + 2, j0 + 3, 4])
    slot_hi = grid.lo + grid.h * np.array([i0 + 5, j0 + 9, grid.shape[2]])
    overlap = np.minimum(cut[:, :3] + cut[:, 3:], slot_hi) - np.maximum(cut[:, :3] - cut[:, 3:], slot_lo)
    assert not np.any(np.all(overlap > 1e-9, axis=1))


def test_overlay_text_and_drawing():
    v = OverlayValues(time=24.0, stage="milling", cut_fraction=0.4, spindle_speed=1000.0, cutting_force=1.5, detached=False)
    lines = overlay_lines(v)
    assert lines[0].split() == ["t", "24.0", "s", "milling"]
    assert "cut  40 %" in lines[1] and "9549 rpm" in lines[2] and "1.500 N" in lines[2]
    frame = np.full((240, 640, 3), 200, np.uint8)
    drawn = draw_overlay(frame, lines, 240)
    changed = np.abs(drawn.astype(int) - frame).sum(axis=2) > 0
    rows, cols = np.nonzero(changed)
    assert rows.max() < 80 and cols.max() < 320  # top-left corner of the first tile only
    assert (drawn[rows, cols] != 200).any() and np.array_equal(draw_overlay(frame, (), 240), frame)


def test_overview_is_framed_on_the_plate():
    """The plate spans at least a third of the overview's width and the sky less than a tenth of its
    rows (a ray through the top-centre pixel hits the floor, not the sky)."""
    config = ScenarioConfig.default()
    w, h = config.simulation.video_width, config.simulation.video_height
    _, model = build_scene_model(config)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    plate = config.layout.plate
    x0, y0 = plate.corner_x - plate.size[0], plate.corner_y
    corners = np.array([[x, y, plate.top_z] for x in (x0, plate.corner_x) for y in (y0, y0 + plate.size[1])])
    px = project_points(model, data, "overview", corners, w, h)
    assert np.ptp(np.clip(px[:, 0], 0, w)) >= w / 3
    cam = model.camera("overview").id
    rot = data.cam_xmat[cam].reshape(3, 3)
    f = 0.5 * h / np.tan(np.radians(model.cam_fovy[cam]) / 2)
    ray = rot @ np.array([0.0, h / 2 - 0.1 * h, -f])  # through the pixel 10 % of the height below the top edge
    assert ray[2] < 0  # looks down at the floor there: at most the top tenth can be sky


def test_overlay_option_is_a_checked_boolean():
    from continuum_sim.configio import ConfigError
    from continuum_sim.scenario.config import SimulationConfig

    assert SimulationConfig().video_overlay is True  # on by default (docs/video.md)
    with pytest.raises(ConfigError, match="video_overlay"):
        SimulationConfig(video_overlay="no")  # type: ignore[arg-type]
