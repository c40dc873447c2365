"""SoRoSim Cosserat-rod release dynamics (``validation/sorosim/sorosim_dynamics``) and the rod's answer.

File layout (tab-separated, 13 columns; data README): line 1 holds the case's damping
(first value) and gravity (last three); line 2 the holding wrenches before release,
``0, mid moment(3), mid force(3), tip moment(3), tip force(3)`` (N·m, N, fixed file frame;
the moment-then-force order is the statics files' Eul-then-P order and is checked by a
test: the other order misses the t = 0 row by tens of centimetres); lines 3+ are
``t, mid Euler(3), mid position(3), tip Euler(3), tip position(3)`` every 5 ms for 10 s.

Reproduction: the capsule rod of ``model/rod.py`` is brought to static equilibrium under
the file's gravity and holding wrenches (``StaticSolver``), the wrenches are removed at
t = 0 and MuJoCo integrates from rest.

Damping map (no fitted constant): SoRoSim damps the strain rates with a matrix
proportional to the stiffness one (a Kelvin–Voigt material, dissipative stress η·ε̇ with
η/E the same for every strain), so the file's damping value is read as the time constant
τ = η/E in seconds and every joint spring k gets a damper c = τ·k (``dof_damping`` =
τ·``jnt_stiffness``): bending c = τ·EI/h, twist c = τ·k_twist. The per-case value in the
file is used as is; that τ (and not, e.g., η in Pa·s, which would leave the steel rod
undamped for 10 s, ζ ~ 1e-13) is what the data show: with it the records match.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..configio import ConfigError
from ..model.rod import RodSpec, apply_node_wrench, compile_rod, node_body_ids
from .sorosim import STEEL, TPU, SorosimRod, data_dir
from .statics import StaticSolver

Array = NDArray[np.float64]

DYNAMICS_FILES = {STEEL.name: "SpringSteelRodMuJoCo_{k}.txt", TPU.name: "TPURodMuJoCo_{k}.txt"}
CASES = tuple(range(1, 11))
# Discretisation per rod: converged enough that the tip RMS sits well inside 1 % of L
# (measured, docs/validation.md: steel 20 links 0.27 %, TPU 40 links 0.54 % on case 1).
LINKS = {STEEL.name: 20, TPU.name: 40}
TIMESTEP = 5e-4  # s; 1e-4 changes the steel/TPU tip RMS by < 0.1 % of L


@dataclass(frozen=True)
class ReleaseCase:
    """One release record: loads before t = 0 and the reference mid/tip trajectories."""

    rod: str
    index: int
    damping: float  # the file's value, read as τ = η/E (s)
    gravity: Array  # (3,)
    mid_wrench: Array  # (6,) force, moment (MuJoCo xfrc order)
    tip_wrench: Array  # (6,)
    time: Array  # (k,)
    mid: Array  # (k, 3) positions, m
    tip: Array  # (k, 3)


def load_release(rod: SorosimRod, index: int, directory: Path | None = None) -> ReleaseCase:
    """Release case ``index`` (1–10) of ``rod``."""
    path = (directory or data_dir()) / "sorosim_dynamics" / DYNAMICS_FILES[rod.name].format(k=index)
    if not path.is_file():
        raise ConfigError("CONTINUUM_SIM_SOROSIM", f"SoRoSim dynamics file not found: {path}")
    table = np.loadtxt(path)
    if table.ndim != 2 or table.shape[1] != 13 or table.shape[0] < 3:
        raise ValueError(f"{path}: expected 13 columns and at least 3 lines, got shape {table.shape}")
    head, hold, body = table[0], table[1], table[2:]
    mid_moment, mid_force, tip_moment, tip_force = hold[1:4], hold[4:7], hold[7:10], hold[10:13]
    return ReleaseCase(
        rod=rod.name,
        index=index,
        damping=float(head[0]),
        gravity=head[10:13].copy(),
        mid_wrench=np.concatenate([mid_force, mid_moment]),
        tip_wrench=np.concatenate([tip_force, tip_moment]),
        time=body[:, 0].copy(),
        mid=body[:, 4:7].copy(),
        tip=body[:, 10:13].copy(),
    )


@dataclass(frozen=True)
class Trajectory:
    time: Array
    mid: Array
    tip: Array


def simulate_release(
    rod: SorosimRod, case: ReleaseCase, n_links: int | None = None, timestep: float = TIMESTEP, damping_scale: float = 1.0
) -> Trajectory:
    """The rod's mid and tip positions at the record's times after release from equilibrium.

    ``damping_scale`` multiplies τ (1 = the documented map; other values only for the
    sensitivity figures in the docs).
    """
    import mujoco

    n = n_links or LINKS[rod.name]
    if n % 2:
        raise ConfigError("n_links", f"must be even so that a node sits at s = L/2 (got {n})")
    spec = RodSpec(rod.length, rod.radius, rod.youngs_modulus, rod.poisson_ratio, rod.density, n, "ball_twist", 0.0, timestep)
    model = compile_rod(spec)
    tau = damping_scale * case.damping
    model.dof_damping[:] = tau * model.jnt_stiffness[model.dof_jntid]
    data = mujoco.MjData(model)
    nodes = node_body_ids(model, n)
    mid_body, tip_body = nodes[n // 2], nodes[-1]
    apply_node_wrench(model, data, mid_body, case.mid_wrench[:3], case.mid_wrench[3:])
    apply_node_wrench(model, data, tip_body, case.tip_wrench[:3], case.tip_wrench[3:])
    result = StaticSolver(model, data).solve(case.gravity, data.xfrc_applied.copy())
    if not result.converged:
        raise RuntimeError(f"{rod.name} case {case.index}: holding equilibrium did not converge")
    data.xfrc_applied[:] = 0.0
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    steps = np.rint(np.diff(case.time, prepend=case.time[0]) / timestep).astype(int)
    mid = np.empty((len(case.time), 3))
    tip = np.empty_like(mid)
    for i, count in enumerate(steps):
        for _ in range(count):
            mujoco.mj_step(model, data)
        mid[i] = data.xpos[mid_body]
        tip[i] = data.xpos[tip_body]
    return Trajectory(case.time.copy(), mid, tip)


# ----------------------------------------------------------------------- swing measures
def swing_signal(tip: Array) -> Array:
    """The tip's displacement from its final rest along the main swing direction (m)."""
    offset = tip - tip[-1]
    _, _, vt = np.linalg.svd(offset - offset.mean(axis=0), full_matrices=False)
    return offset @ vt[0]


def _peaks(t: Array, x: Array, floor: float) -> tuple[Array, Array]:
    """Times and |x| of the extrema of x (sign changes of its slope) above ``floor``."""
    dx = np.diff(x)
    idx = np.flatnonzero(np.sign(dx[1:]) != np.sign(dx[:-1])) + 1
    idx = idx[np.abs(x[idx]) > floor]
    if len(idx) == 0:
        return np.empty(0), np.empty(0)
    # parabolic refinement through the three samples around each extremum
    ym, y0, yp = x[idx - 1], x[idx], x[np.minimum(idx + 1, len(x) - 1)]
    denom = ym - 2.0 * y0 + yp
    shift = np.where(np.abs(denom) > 0, 0.5 * (ym - yp) / np.where(denom == 0, 1, denom), 0.0)
    dt = t[1] - t[0]
    return t[idx] + shift * dt, np.abs(y0 - 0.25 * (ym - yp) * shift)


@dataclass(frozen=True)
class Swing:
    frequency: float  # Hz, from the mean half-period between zero crossings
    decay_rate: float  # 1/s, σ of the envelope A·exp(−σt) fitted to the extrema
    peaks: int


def _zero_crossings(t: Array, x: Array) -> Array:
    """Times where x changes sign, linearly interpolated."""
    idx = np.flatnonzero(np.sign(x[1:]) * np.sign(x[:-1]) < 0)
    return t[idx] - x[idx] * (t[idx + 1] - t[idx]) / (x[idx + 1] - x[idx])


def swing(t: Array, tip: Array, floor_fraction: float = 0.05, max_peaks: int = 20) -> Swing:
    """First-mode swing of a release: frequency from zero crossings, decay from extrema.

    The window runs from the release to the last extremum above ``floor_fraction`` of the
    largest swing (at most ``max_peaks`` extrema): below it the data's 0.1 mm rounding
    and slower modes dominate. Zero crossings of the main swing are insensitive to the
    small higher-mode ripple that adds spurious extrema, so they give the frequency.
    """
    x = swing_signal(tip)
    floor = floor_fraction * np.abs(x).max()
    times, amps = _peaks(t, x, floor)
    times, amps = times[:max_peaks], amps[:max_peaks]
    if len(times) < 4:
        raise ValueError("fewer than 4 swing extrema above the floor")
    crossings = _zero_crossings(t, x)
    crossings = crossings[crossings <= times[-1]]
    if len(crossings) < 3:
        raise ValueError("fewer than 3 zero crossings in the swing window")
    frequency = 1.0 / (2.0 * np.mean(np.diff(crossings)))
    slope = np.polyfit(times, np.log(amps), 1)[0]
    return Swing(float(frequency), float(-slope), len(times))


@dataclass(frozen=True)
class ReleaseComparison:
    rod: str
    case: int
    n_links: int
    tip_rms_pct: float  # % of L over the record
    tip_max_pct: float
    mid_rms_pct: float
    frequency_ref: float
    frequency_model: float
    decay_ref: float
    decay_model: float

    @property
    def frequency_error_pct(self) -> float:
        return 100.0 * (self.frequency_model / self.frequency_ref - 1.0)

    @property
    def decay_error_pct(self) -> float:
        return 100.0 * (self.decay_model / self.decay_ref - 1.0)


def compare_release(
    rod: SorosimRod, index: int, n_links: int | None = None, damping_scale: float = 1.0
) -> tuple[ReleaseComparison, ReleaseCase, Trajectory]:
    """Simulate release ``index`` of ``rod`` and measure it against the record."""
    case = load_release(rod, index)
    sim = simulate_release(rod, case, n_links, damping_scale=damping_scale)
    tip_err = np.linalg.norm(sim.tip - case.tip, axis=1)
    mid_err = np.linalg.norm(sim.mid - case.mid, axis=1)
    ref_swing, model_swing = swing(case.time, case.tip), swing(sim.time, sim.tip)
    result = ReleaseComparison(
        rod=rod.name,
        case=index,
        n_links=n_links or LINKS[rod.name],
        tip_rms_pct=float(100.0 * np.sqrt(np.mean(tip_err**2)) / rod.length),
        tip_max_pct=float(100.0 * tip_err.max() / rod.length),
        mid_rms_pct=float(100.0 * np.sqrt(np.mean(mid_err**2)) / rod.length),
        frequency_ref=ref_swing.frequency,
        frequency_model=model_swing.frequency,
        decay_ref=ref_swing.decay_rate,
        decay_model=model_swing.decay_rate,
    )
    return result, case, sim
