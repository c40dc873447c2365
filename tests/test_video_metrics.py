"""Off-screen video recording and the metric helpers."""

import numpy as np
import pytest

from continuum_sim import distances
from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.scenario import metrics as met

choose_gl_backend()
import mujoco  # noqa: E402

SCENE = """
<mujoco>
  <worldbody>
    <light pos="0 0 2"/>
    <camera name="a" pos="0 -1 0.3" xyaxes="1 0 0 0 0.3 1"/>
    <camera name="b" pos="1 0 0.3" xyaxes="0 1 0 -0.3 0 1"/>
    <body pos="0 0 0.5"><freejoint/><geom type="box" size=".05 .05 .05" rgba="1 0 0 1"/></body>
    <geom type="plane" size="1 1 .1"/>
  </worldbody>
</mujoco>
"""


def test_video_recorder_writes_tiled_mp4_atomically(tmp_path):
    import imageio.v2 as imageio

    from continuum_sim.video import VideoRecorder

    model = mujoco.MjModel.from_xml_string(SCENE)
    data = mujoco.MjData(model)
    path = tmp_path / "clip.mp4"
    with VideoRecorder(model, path, ["a", "b"], width=160, height=120, fps=20) as video:
        while data.time < 0.5:
            mujoco.mj_step(model, data)
            video.maybe_capture(data)
            assert not path.exists()  # only the finished file appears under its name
    assert video.frames == 11  # t = 0, 0.05, …, 0.5
    reader = imageio.get_reader(path)
    frames = [f for f in reader]
    reader.close()
    assert len(frames) == 11
    assert frames[0].shape == (120, 320, 3)
    assert frames[-1].std() > 5  # something was drawn
    assert not list(tmp_path.glob(".*partial*"))


def _record_clip(path, workers: int, chunk_frames: int = 60, reports: list | None = None) -> int:
    """Record 0.5 s of the falling box; the box turns invisible at t = 0.25 s (a run changing colours)."""
    from continuum_sim.video import VideoRecorder

    model = mujoco.MjModel.from_xml_string(SCENE)
    data = mujoco.MjData(model)
    box = int(model.body_geomadr[1])  # the falling box's geom
    with VideoRecorder(model, path, ["a", "b"], width=160, height=120, fps=20, workers=workers, chunk_frames=chunk_frames) as video:
        while data.time < 0.5:
            mujoco.mj_step(model, data)
            if data.time >= 0.25:
                model.geom_rgba[box, 3] = 0.0
            video.maybe_capture(data)
            assert not path.exists()
        if reports is not None:  # the frames still encoding, chunk by chunk (the run's "video" bar)
            video.wait_for_workers(reports.append)
            assert not path.exists()  # joined only by close()
    return video.frames


def _read_frames(path):
    import imageio.v2 as imageio

    reader = imageio.get_reader(path)
    frames = np.array([f for f in reader], dtype=float)
    reader.close()
    return frames


def test_parallel_video_workers_match_in_process_rendering(tmp_path):
    """Render workers (chunks of 4 frames -> 3 segments joined without re-encoding) give the
    frames the in-process renderer gives, colour changes included, and leave no temporaries."""
    serial, parallel = tmp_path / "serial.mp4", tmp_path / "parallel.mp4"
    assert _record_clip(serial, workers=0) == 11
    reports: list[int] = []
    assert _record_clip(parallel, workers=2, chunk_frames=4, reports=reports) == 11
    assert sorted(reports) == [3, 4, 4]  # every chunk reported once, with its frame count
    a, b = _read_frames(serial), _read_frames(parallel)
    assert a.shape == b.shape == (11, 120, 320, 3)
    assert np.abs(a - b).mean() < 2.0  # same pictures up to the encoder's rounding
    red = lambda f: ((f[..., 0] > f[..., 1] + 60) & (f[..., 0] > f[..., 2] + 60)).sum()  # noqa: E731
    assert red(a[4]) > 50 and red(b[4]) > 50  # the box is drawn …
    assert red(a[-1]) == 0 and red(b[-1]) == 0  # … then hidden after t = 0.25 s
    assert sorted(p.name for p in tmp_path.iterdir()) == ["parallel.mp4", "serial.mp4"]


def test_video_recorder_rejects_unknown_camera(tmp_path):
    from continuum_sim.video import VideoRecorder

    model = mujoco.MjModel.from_xml_string(SCENE)
    with pytest.raises(ValueError, match="cameras: unknown camera 'nope'"):
        VideoRecorder(model, tmp_path / "x.mp4", ["nope"])


def test_polyline_distance_and_axis_angle():
    line = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    pts = np.array([[0.5, 0.2], [1.3, 0.5], [2.0, 2.0], [-1.0, 0.0]])
    np.testing.assert_allclose(distances.polyline_distance(pts, line), [0.2, 0.3, np.sqrt(2), 1.0])
    axes = np.array([[0.0, 0.0, 1.0], [np.sin(0.1), 0.0, np.cos(0.1)]])
    np.testing.assert_allclose(distances.axis_angle_deg(axes, np.array([0, 0, 2.0])), [0.0, np.degrees(0.1)], atol=1e-12)


def test_backbone_distance_is_centre_gap_minus_radii():
    a = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    b = np.array([[0.5, 0.0, 1.0], [3.0, 0.0, 0.0]])
    assert distances.min_backbone_distance(a, np.array([0.1, 0.1]), b, np.array([0.05, 0.05])) == pytest.approx(0.35)


def test_backbone_distance_series_equals_the_per_frame_distance():
    rng = np.random.default_rng(5)
    a, b = rng.normal(size=(300, 7, 3)), rng.normal(size=(300, 5, 3))  # > one chunk of frames
    ra, rb = rng.uniform(0.0, 0.2, 7), rng.uniform(0.0, 0.2, 5)
    series = distances.min_backbone_distances(a, ra, b, rb, chunk=64)
    direct = [np.min(np.linalg.norm(a[i][:, None] - b[i][None], axis=-1) - ra[:, None] - rb[None]) for i in range(300)]
    np.testing.assert_allclose(series, direct, atol=1e-14)


def test_error_stats():
    stats = met.error_stats(np.array([0.001, 0.002, 0.002]))
    assert stats["mean"] == pytest.approx(5 / 3) and stats["max"] == pytest.approx(2.0)
    assert stats["rms"] == pytest.approx(np.sqrt(9 / 3))
    assert met.error_stats(np.array([]))["mean"] is None
