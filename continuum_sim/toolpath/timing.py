"""Rest-to-rest trapezoidal speed profiles: how long a move takes and where it is at a time."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def trapezoid_duration(distance: float, v: float, a: float) -> float:
    """Time to cover ``distance`` from rest to rest with speed ≤ v and acceleration ≤ a."""
    if distance <= 0.0:
        return 0.0
    if distance >= v * v / a:
        return distance / v + v / a
    return 2.0 * math.sqrt(distance / a)


def trapezoid_position(t: Array, distance: float, v: float, a: float) -> Array:
    """Distance covered at times ``t`` along the rest-to-rest trapezoidal profile."""
    t = np.asarray(t, dtype=float)
    if distance <= 0.0:
        return np.zeros_like(t)
    T = trapezoid_duration(distance, v, a)
    vp = min(v, math.sqrt(distance * a))  # peak speed
    ta = vp / a
    s = np.where(
        t < ta,
        0.5 * a * t**2,
        np.where(t <= T - ta, 0.5 * a * ta**2 + vp * (t - ta), distance - 0.5 * a * np.clip(T - t, 0.0, None) ** 2),
    )
    return np.clip(s, 0.0, distance)
