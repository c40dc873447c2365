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
