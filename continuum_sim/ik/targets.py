"""What the solver is given, checked: target poses, configurations, tools, and the arm's frame."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..geometry import ArmGeometry
from .options import Array


def validate_pose(target: ArrayLike, name: str = "target") -> Array:
    """A (4, 4) homogeneous transform with a proper rotation, else a one-line ValueError."""
    T = np.asarray(target, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f"{name}: must be a (4, 4) homogeneous transform (got shape {T.shape})")
    v = T.ravel().tolist()
    if not all(map(math.isfinite, v)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    if max(abs(v[12]), abs(v[13]), abs(v[14]), abs(v[15] - 1.0)) > 1e-9:
        raise ValueError(f"{name}: last row must be [0, 0, 0, 1] (got {v[12:]})")
    a, b, c, d, e, f, g, h, i = v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]
    ortho = max(
        abs(a * a + d * d + g * g - 1.0),
        abs(b * b + e * e + h * h - 1.0),
        abs(c * c + f * f + i * i - 1.0),
        abs(a * b + d * e + g * h),
        abs(a * c + d * f + g * i),
        abs(b * c + e * f + h * i),
    )
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    if ortho > 1e-6 or det < 0.0:
        raise ValueError(
            f"{name}: rotation part is not a rotation matrix (max |RᵀR - I| = {ortho:.3g}, det = {det:.6g}; "
            "allowed: orthonormal within 1e-6 and det = +1)"
        )
    return T


def tool_length_of(geometry: ArmGeometry, tool: str | float) -> float:
    """Tool offset along the tip z: a tool name ('grinder', 'gripper', 'none') or metres."""
    if isinstance(tool, str):
        return geometry.tools.length(tool)
    length = float(tool)
    if not math.isfinite(length) or not 0.0 <= length <= 1.0:
        raise ValueError(f"tool: tool length must satisfy 0 <= tool <= 1 m (got {tool!r})")
    return length


def validate_q(geometry: ArmGeometry, q: ArrayLike, name: str = "q0") -> Array:
    """(θ, φ) per section as a finite float array, else a one-line ValueError."""
    q = np.asarray(q, dtype=float)
    n = 2 * geometry.n_sections
    if q.shape != (n,):
        raise ValueError(f"{name}: must have {n} entries (θ, φ per section), got shape {q.shape}")
    if not all(map(math.isfinite, q.tolist())):
        raise ValueError(f"{name}: contains NaN or infinite values")
    return q


def to_arm_frame(target: Array, base: ArrayLike | None) -> Array:
    """A world ``target`` in the frame of an arm mounted at ``base`` (unchanged when ``base`` is None)."""
    if base is None:
        return target
    B = validate_pose(base, "base")
    Binv = np.eye(4)
    Binv[:3, :3] = B[:3, :3].T
    Binv[:3, 3] = -B[:3, :3].T @ B[:3, 3]
    return Binv @ target
