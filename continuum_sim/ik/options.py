"""The IK problem's modes and the solver's numerical settings (``IKOptions``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..configio import require_int, require_positive, require_range

Array = NDArray[np.float64]
Orientation = Literal["full", "axis"]
Phase = Literal["free", "planar"]
ORIENTATIONS = ("full", "axis")
PHASES = ("free", "planar")


@dataclass(frozen=True)
class IKOptions:
    """Numerical settings of the solver (the problem itself is in ``solve_ik``'s arguments)."""

    position_weight: float = 10.0  # k1 of paper eq. 8, 1/m: 0.1 m of position ~ 1 rad
    orientation_weight: float = 1.0  # k2 of paper eq. 8, 1/rad
    position_tolerance: float = 1e-9  # m: success means both errors are within tolerance
    orientation_tolerance: float = 1e-9  # rad
    max_iterations: int = 60  # Levenberg-Marquardt iterations per start
    n_starts: int = 12  # cold starts tried (best-first from the seed table)
    seed_table_size: int = 384  # configurations in the cold-start table
    seed: int = 0  # of the seed table: same seed, same table, same answers
    max_step_rad: float = 0.6  # per-iteration trust radius per section, in bending coordinates

    def __post_init__(self) -> None:
        require_positive("position_weight", self.position_weight)
        require_positive("orientation_weight", self.orientation_weight)
        require_range("position_tolerance", self.position_tolerance, 0.0, 0.1)
        require_range("orientation_tolerance", self.orientation_tolerance, 0.0, 0.5)
        require_int("max_iterations", self.max_iterations, 1, 10_000)
        require_int("n_starts", self.n_starts, 1, 1000)
        require_int("seed_table_size", self.seed_table_size, 1, 100_000)
        require_int("seed", self.seed, 0, 2**32 - 1)
        require_range("max_step_rad", self.max_step_rad, 0.0, 10.0)


def check_mode(orientation: str, phase: str) -> None:
    """A one-line ValueError naming the allowed modes."""
    if orientation not in ORIENTATIONS:
        raise ValueError(f"orientation: must be one of {', '.join(ORIENTATIONS)} (got {orientation!r})")
    if phase not in PHASES:
        raise ValueError(f"phase: must be one of {', '.join(PHASES)} (got {phase!r})")
