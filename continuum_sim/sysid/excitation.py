"""The excitation motion, and recordings synthesised from the model (``continuum-sim synthesize``).

The excitation (docs/sysid.md): a sequence of key shapes in bending coordinates
(u, v) = θ(cos φ, sin φ) per section, joined by smooth (cosine, zero end-velocity)
transitions, each followed by a hold:

1. each section alone, base to tip: +u, 0, −u, 0, +v, 0, −v, 0 (both directions of its
   bending range in both planes, with reversals through the straight shape);
2. all sections together: +u, −u (a full reversal of the whole arm), +v, −v;
3. alternating sections (+u, −u, +u, …) and its mirror (an S-shape: the distal cables
   load the proximal sections against their own cables);
4. back to straight.

Amplitude: ``amplitude`` × each section's ``max_bend``. Holds let the slow modes (and
any stick-slip) settle, so static stiffness, cable stretch and friction each leave a
mark; the moves excite the dynamics. Transitions take 60 % and holds 40 % of each step.
Cable set-points are the PCC cable-length changes of the shape (SPEC §2) on the model's
geometry, exactly what the package's open-loop controller commands.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from .. import kinematics as kin
from ..configio import ConfigError, require_range
from ..model.options import model_geometry
from ..scenario.config import ScenarioConfig
from .data import Recording, RecordingInfo
from .replay import simulate

Array = NDArray[np.float64]


def key_shapes(n_sections: int) -> Array:
    """(K, 2·n) key shapes in units of each section's amplitude (bending coordinates)."""
    keys: list[list[float]] = []
    for k in range(n_sections):
        for u, v in ((1, 0), (0, 0), (-1, 0), (0, 0), (0, 1), (0, 0), (0, -1), (0, 0)):
            w = [0.0] * (2 * n_sections)
            w[2 * k], w[2 * k + 1] = float(u), float(v)
            keys.append(w)
    for u, v in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        keys.append([float(x) for _ in range(n_sections) for x in (u, v)])
    for sign in (1, -1):
        keys.append([float(x) for k in range(n_sections) for x in (sign * (-1) ** k, 0.0)])
    keys.append([0.0] * (2 * n_sections))
    return np.array(keys)


def excitation(config: ScenarioConfig, duration: float, rate_hz: float, amplitude: float = 0.5) -> tuple[Array, Array]:
    """Times (N,) and bending coordinates (N, 2·n) of the excitation, sampled at ``rate_hz``."""
    require_range("--duration", duration, 0.0, 3600.0)
    require_range("--rate", rate_hz, 0.0, 10000.0)
    require_range("--amplitude", amplitude, 0.0, 1.0)
    geometry = config.arm
    keys = key_shapes(geometry.n_sections) * np.repeat(geometry.max_bend * amplitude, 2)
    keys = np.vstack([np.zeros((1, keys.shape[1])), keys])
    step = duration / (len(keys) - 1)
    move, hold = 0.6 * step, 0.4 * step
    n = int(np.floor(duration * rate_hz)) + 1
    if n < 2:
        raise ConfigError("--duration", f"gives fewer than 2 samples at {rate_hz:g} Hz")
    t = np.arange(n) / rate_hz
    i = np.minimum((t // step).astype(int), len(keys) - 2)
    s = np.clip((t - i * step) / move, 0.0, 1.0)
    blend = 0.5 - 0.5 * np.cos(np.pi * s)
    w = keys[i] + (keys[i + 1] - keys[i]) * blend[:, None]
    del hold
    return t, w


def synthesize(config: ScenarioConfig, arm: str = "left", duration: float = 20.0, rate_hz: float = 50.0,
               noise_mm: float = 0.0, noise_deg: float = 0.0, seed: int = 0, amplitude: float = 0.5,
               mode: str = "dynamic", settle_s: float = 0.5, gravity: bool = True) -> Recording:
    """A recording of ``arm`` made by the model of ``config`` along the excitation, with noise.

    Noise: independent Gaussian per position axis (σ = ``noise_mm``) and a rotation by a
    Gaussian rotation vector (σ = ``noise_deg`` per axis). Tensions are the model's,
    without noise. Times lie on the physics step grid, so a replay reads poses exactly.
    """
    require_range("--noise-mm", noise_mm, 0.0, 1000.0, low_inclusive=True)
    require_range("--noise-deg", noise_deg, 0.0, 90.0, low_inclusive=True)
    dt = config.model.timestep
    rate_hz = 1.0 / (dt * max(1, round(1.0 / (rate_hz * dt))))
    t, w = excitation(config, duration, rate_hz, amplitude)
    geometry = model_geometry(config.arm, config.model)
    delta = kin.cable_lengths_bending(geometry, w) - kin.straight_cable_lengths(geometry)
    n = len(t)
    info = RecordingInfo(mode=mode, settle_s=float(settle_s), gravity=gravity, tool="auto", align="none",
                         source="continuum-sim synthesize")
    template = Recording(arm, t, delta, np.zeros((n, 3)), np.tile([1.0, 0, 0, 0], (n, 1)), None, None, None, None, info)
    (pred,) = simulate([config], template)
    if not np.all(np.isfinite(pred.position)):
        raise ConfigError("synthesize", "the model diverged along the excitation (check the --set values)")
    rng = np.random.default_rng(seed)
    pos = pred.position + rng.normal(0.0, noise_mm / 1000.0, size=(n, 3))
    rv = rng.normal(0.0, np.radians(noise_deg), size=(n, 3))
    quat = np.array([_quat_mul(q, _quat_from_rotvec(r)) for q, r in zip(pred.quaternion, rv)])
    quat *= np.sign(quat[:, :1] + 1e-300)
    return dataclasses.replace(template, position=pos, quaternion=quat, tensions=np.maximum(pred.tension, 0.0))


def _quat_from_rotvec(r: Array) -> Array:
    a = float(np.linalg.norm(r))
    if a < 1e-15:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return np.concatenate([[np.cos(a / 2)], np.sin(a / 2) * r / a])


def _quat_mul(a: Array, b: Array) -> Array:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])
