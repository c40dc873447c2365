import numpy as np
import pytest

from continuum_sim import ArmGeometry


@pytest.fixture(scope="session")
def geometry() -> ArmGeometry:
    return ArmGeometry.default()


def random_q(rng: np.random.Generator, geometry: ArmGeometry, n: int | None = None) -> np.ndarray:
    """Random configurations inside the bending limits."""
    shape = (geometry.n_sections,) if n is None else (n, geometry.n_sections)
    theta = rng.uniform(0.0, 1.0, shape) * geometry.max_bend
    phi = rng.uniform(-np.pi, np.pi, shape)
    q = np.empty(shape[:-1] + (2 * geometry.n_sections,))
    q[..., 0::2] = theta
    q[..., 1::2] = phi
    return q


# Frames of the default run's close-up video (tests/test_video_kerf.py): every 12 s of simulated time.
CLOSEUP_EVERY_S = 12.0


@pytest.fixture(scope="session")
def default_run(tmp_path_factory):
    """The shipped default run, once per session: (run folder, metrics, close-up video path).

    Besides the run folder it records the run's close-up camera through the video's own
    observer (kerf voxels, overlay, MP4 encoder), in-process, one frame every
    ``CLOSEUP_EVERY_S`` simulated seconds (0, 12, 24, 36, 48 s): the video only reads the
    state, so the physics and metrics are the default run's.
    """
    from continuum_sim.glbackend import choose_gl_backend

    choose_gl_backend()
    from continuum_sim.scenario.config import ScenarioConfig, merged
    from continuum_sim.scenario.runner import run_scenario
    from continuum_sim.scenario.simulate import Observer
    from continuum_sim.scenario.video_observer import VideoObserver

    config = ScenarioConfig.default()
    closeup = merged(config, {"simulation": {"cameras": ["closeup"]}}).simulation
    video_path = tmp_path_factory.mktemp("closeup") / "closeup.mp4"

    class CloseupVideo(Observer):
        def start(self, sim):
            self.video = VideoObserver(sim, video_path, closeup, fps=1.0 / CLOSEUP_EVERY_S, workers=0)

        def after_tick(self, sim):
            return self.video.after_tick(sim)

        def close(self, sim):
            self.video.close(sim)

    out = tmp_path_factory.mktemp("default_run")
    return out, run_scenario(config, out, observers=[CloseupVideo()]), video_path


@pytest.fixture(scope="session")
def report_run(tmp_path_factory):
    """A short run folder (first stage, with a tiny video.mp4) shared by the report tests; treat as read-only."""
    from report_helpers import make_short_run

    out = tmp_path_factory.mktemp("report_run") / "run"
    make_short_run(out)
    return out


@pytest.fixture(scope="session")
def report_sweep(tmp_path_factory):
    """A two-variant gravity_sag sweep folder shared by the report tests; copy before changing it."""
    from report_helpers import make_tiny_sweep

    return make_tiny_sweep(tmp_path_factory.mktemp("report_sweep"))
