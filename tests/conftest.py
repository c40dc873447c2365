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
