"""Static Cosserat-rod model of a tendon-driven continuum robot (Rucker & Webster, IEEE T-RO 27(6), 2011).

An independent reference for the cable-driven arm: it shares no code with the MuJoCo
model (no kinematics, no tendon sites, no joints), only the design data — lengths, cable
hole positions, disk masses — and the sections' rigidities EI, GJ from
``continuum_sim.model.stiffness`` (so it follows any change of the segment formula).

Model. The backbone is a Kirchhoff rod (inextensible and unshearable, v = e₃: the arm's
central joints carry axial and shear loads rigidly), arc length s ∈ [0, L], position p,
orientation R, body-frame curvature u, constitutive law m_rod = R·K·u with
K = diag(EI_x, EI_y, GJ) of the section at s. Tendon i runs at the fixed body-frame offset
r_i (a straight, parallel routing: r_i' = 0) from the base to its termination s_i, with
tension τ_i, frictionless. Its path tangent is
t_i = R·(e₃ + u × r_i)/|e₃ + u × r_i|   (p_i = p + R r_i ⇒ p_i' = R(e₃ + u × r_i)).

Rucker & Webster write the tendons' effect as a distributed force/moment on the backbone
plus point loads at each termination. Cutting the robot at s and balancing everything
distal of the cut (rod *and* tendons) gives the same equations in a form that needs no
tendon curvature: the total internal force n and moment m (rod plus the tendons' cut
tensions, exerted by the distal part on the proximal one, moment about p(s)) obey the
plain rod equations with only the external loads,

    n' = −f,   m' = −p' × n − l,   n(L) = F_tip,   m(L) = M_tip,

(f = ρA·g per length; l = 0), while the rod itself carries what the tendons do not:

    R·K·u + Σ_{i: s < s_i} τ_i·(R r_i) × t_i(u) = m.

The last relation is solved for u at every s (Newton, 3×3); a termination s_i is a jump
of the tendons' share, i.e. the point moment R&W apply there. The boundary-value problem
(unknown n(0), m(0)) is solved by shooting (``scipy.optimize.root`` on the tip residual,
``solve_ivp`` DOP853 between terminations).

Analytic limit (checked by a test): one tendon, no gravity, no tip load ⇒
K·u = −τ r × e₃ with u × r ∥ e₃, i.e. a constant curvature κ = τ·r/EI and a circular arc.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..configio import ConfigError, require_range

Array = NDArray[np.float64]

E3 = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class RodPiece:
    """A stretch of backbone with uniform rigidity and weight."""

    length: float  # m
    bending_x: float  # EI about body x, N·m²
    bending_y: float  # EI about body y, N·m²
    twist: float  # GJ, N·m² (math.inf: twist locked, e.g. a universal central joint)
    mass_per_length: float  # kg/m

    def __post_init__(self) -> None:
        require_range("length", self.length, 0.0, 100.0)
        require_range("bending_x", self.bending_x, 0.0, 1e9)
        require_range("bending_y", self.bending_y, 0.0, 1e9)
        if not (self.twist > 0.0):
            raise ConfigError("twist", f"must be > 0 (got {self.twist!r})")
        require_range("mass_per_length", self.mass_per_length, 0.0, 1e6, low_inclusive=True)


@dataclass(frozen=True)
class Tendon:
    """A tendon at body-frame offset (x, y) from the backbone, terminated at arc length ``end``."""

    offset: tuple[float, float]  # m
    end: float  # m from the base
    tension: float  # N (≥ 0: tendons pull)

    def __post_init__(self) -> None:
        if not self.tension >= 0.0:
            raise ConfigError("tension", f"must be >= 0 (got {self.tension!r})")
        if not self.end > 0.0:
            raise ConfigError("end", f"must be > 0 (got {self.end!r})")


@dataclass(frozen=True)
class CosseratRobot:
    """Backbone pieces base→tip, tendons, gravity (m/s², base frame) and a tip wrench."""

    pieces: tuple[RodPiece, ...]
    tendons: tuple[Tendon, ...]
    gravity: tuple[float, ...] = (0.0, 0.0, 0.0)
    tip_force: tuple[float, ...] = (0.0, 0.0, 0.0)
    tip_moment: tuple[float, ...] = (0.0, 0.0, 0.0)
    point_masses: tuple[tuple[float, float], ...] = field(default_factory=tuple)  # (s, kg): lumped masses

    @property
    def length(self) -> float:
        return float(sum(p.length for p in self.pieces))

    def breaks(self) -> Array:
        """Arc lengths where the integrand changes: piece ends, terminations, point masses."""
        ends = np.cumsum([p.length for p in self.pieces])
        pts = [0.0, *ends, *(t.end for t in self.tendons), *(s for s, _ in self.point_masses)]
        return np.unique(np.round(np.clip(np.asarray(pts, dtype=float), 0.0, self.length), 12))

    def piece_at(self, s: float) -> RodPiece:
        ends = np.cumsum([p.length for p in self.pieces])
        return self.pieces[min(int(np.searchsorted(ends, s, side="right")), len(self.pieces) - 1)]


@dataclass(frozen=True)
class CosseratSolution:
    s: Array  # (k,) arc lengths, base→tip
    positions: Array  # (k, 3)
    rotations: Array  # (k, 3, 3)
    curvatures: Array  # (k, 3) body-frame u
    residual: float  # max tip-BC residual (N, N·m)
    converged: bool

    @property
    def tip(self) -> Array:
        return self.positions[-1]

    def position_at(self, s: float) -> Array:
        return np.array([np.interp(s, self.s, self.positions[:, k]) for k in range(3)])


def _hat(v: Array) -> Array:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _tendon_moment(u: Array, offsets: Array, tensions: Array, jacobian: bool = False):
    """Σ τ_i r_i × t̂_i(u) in the body frame (t̂: unit tendon tangent, body frame), and its ∂/∂u.

    d_i = e₃ + u × r_i = e₃ − [r_i]× u, t̂_i = d_i/|d_i|, so
    ∂(r_i × t̂_i)/∂u = −[r_i]× (I − t̂_i t̂_iᵀ)/|d_i| [r_i]×.
    """
    r = np.column_stack([offsets, np.zeros(len(offsets))])
    d = E3 + np.cross(u, r)
    norm = np.linalg.norm(d, axis=1)
    t = d / norm[:, None]
    moment = (tensions[:, None] * np.cross(r, t)).sum(axis=0)
    if not jacobian:
        return moment
    jac = np.zeros((3, 3))
    eye = np.eye(3)
    for ri, ti, ni, tau in zip(r, t, norm, tensions):
        rx = _hat(ri)
        jac -= tau / ni * rx @ (eye - np.outer(ti, ti)) @ rx
    return moment, jac


def solve_curvature(m_body: Array, piece: RodPiece, offsets: Array, tensions: Array, u0: Array | None = None) -> Array:
    """u with K·u + Σ τ r × t̂(u) = m_body (Newton, analytic 3×3 Jacobian; twist held 0 when GJ = ∞)."""
    locked = not math.isfinite(piece.twist)
    k = np.array([piece.bending_x, piece.bending_y, 1.0 if locked else piece.twist])
    if len(tensions) == 0:  # no tendon: the plain constitutive law
        u = m_body / k
        if locked:
            u[2] = 0.0
        return u
    u = np.zeros(3) if u0 is None else u0.copy()
    dim = 2 if locked else 3
    if locked:
        u[2] = 0.0
    scale = float(np.abs(m_body).max()) + float(tensions.sum()) * float(np.abs(offsets).max()) + 1e-300
    for _ in range(50):
        moment, jac = _tendon_moment(u, offsets, tensions, jacobian=True)
        g = (k * u + moment - m_body)[:dim]
        if np.abs(g).max() <= 1e-14 * scale:
            break
        u[:dim] -= np.linalg.solve(np.diag(k[:dim]) + jac[:dim, :dim], g)
    return u


class CosseratSolver:
    """Shooting solver of ``CosseratRobot`` statics."""

    def __init__(self, robot: CosseratRobot, rtol: float = 1e-9, atol: float = 1e-12) -> None:
        self.robot = robot
        self.rtol, self.atol = rtol, atol
        self.gravity = np.asarray(robot.gravity, dtype=float)
        self._u_guess = np.zeros(3)

    def _active(self, s: float) -> tuple[Array, Array]:
        tendons = [t for t in self.robot.tendons if s < t.end - 1e-12]
        if not tendons:
            return np.zeros((0, 2)), np.zeros(0)
        return np.array([t.offset for t in tendons], dtype=float), np.array([t.tension for t in tendons], dtype=float)

    def _rhs_factory(self, offsets: Array, tensions: Array, piece: RodPiece):
        f = piece.mass_per_length * self.gravity

        def rhs(_s: float, y: Array) -> Array:
            rot = y[3:12].reshape(3, 3)
            n, m = y[12:15], y[15:18]
            u = solve_curvature(rot.T @ m, piece, offsets, tensions, self._u_guess)
            self._u_guess = u
            dp = rot[:, 2]
            dR = rot @ _hat(u)
            return np.concatenate([dp, dR.ravel(), -f, -np.cross(dp, n)])

        return rhs

    def integrate(self, n0: Array, m0: Array, dense: bool = False):
        """Integrate base→tip from total wrench (n0, m0); returns tip state (and samples)."""
        from scipy.integrate import solve_ivp

        y = np.concatenate([np.zeros(3), np.eye(3).ravel(), n0, m0])
        breaks = self.robot.breaks()
        # each lumped mass acts at the break nearest to it (breaks are rounded to 1e-12 m)
        at_break: dict[int, float] = {}
        for s_mass, mass in self.robot.point_masses:
            k = int(np.argmin(np.abs(breaks - s_mass)))
            at_break[k] = at_break.get(k, 0.0) + mass
        samples_s, samples_y = [0.0], [y.copy()]
        self._u_guess = np.zeros(3)
        for k, (a, b) in enumerate(itertools.pairwise(breaks), start=1):
            mid = 0.5 * (a + b)
            offsets, tensions = self._active(mid)
            rhs = self._rhs_factory(offsets, tensions, self.robot.piece_at(mid))
            sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=self.rtol, atol=self.atol, dense_output=dense)
            y = sol.y[:, -1].copy()
            if dense:
                grid = np.linspace(a, b, max(3, math.ceil((b - a) / 0.002) + 1))[1:]
                samples_s.extend(grid)
                samples_y.extend(sol.sol(grid).T)
            # a lumped mass at b: the internal force drops by its weight across it
            if k in at_break:
                y[12:15] -= at_break[k] * self.gravity
                if dense:
                    samples_y[-1] = y.copy()
        return y, np.array(samples_s), np.array(samples_y)

    def residual(self, x: Array) -> Array:
        y, _, _ = self.integrate(x[:3], x[3:])
        scale = np.array([1.0, 1.0, 1.0, 1.0 / self.robot.length, 1.0 / self.robot.length, 1.0 / self.robot.length])
        # moment residual in N (divided by L) so force and moment weigh alike
        return np.concatenate([y[12:15] - np.asarray(self.robot.tip_force), y[15:18] - np.asarray(self.robot.tip_moment)]) * scale

    def initial_guess(self) -> Array:
        """Total base wrench of the straight robot under its external loads (exact without gravity)."""
        total_mass = sum(p.mass_per_length * p.length for p in self.robot.pieces) + sum(m for _, m in self.robot.point_masses)
        weight = total_mass * self.gravity
        n0 = np.asarray(self.robot.tip_force) + weight
        # moment of gravity about the base of the straight robot (along z)
        moment = np.zeros(3)
        s0 = 0.0
        for p in self.robot.pieces:
            moment += np.cross(E3 * (s0 + p.length / 2.0), p.mass_per_length * p.length * self.gravity)
            s0 += p.length
        for s, m in self.robot.point_masses:
            moment += np.cross(E3 * s, m * self.gravity)
        m0 = np.asarray(self.robot.tip_moment) + np.cross(E3 * self.robot.length, np.asarray(self.robot.tip_force)) + moment
        return np.concatenate([n0, m0])

    def _shoot(self, x0: Array) -> tuple[Array, float, bool]:
        from scipy.optimize import root

        sol = root(self.residual, x0, method="hybr", options={"xtol": 1e-12})
        res = float(np.abs(self.residual(sol.x)).max())
        return sol.x, res, bool(sol.success or res < 1e-9)

    def solve(self, guess: Array | None = None, ramps: tuple[int, ...] = (1, 4, 16)) -> CosseratSolution:
        """Shoot from ``guess`` (default: the straight robot's base wrench); when that fails,
        continue in the load: gravity, tensions and tip loads scaled k/steps, k = 1…steps,
        each step starting from the last (large self-weight bends need it)."""
        x0 = self.initial_guess() if guess is None else guess
        x, res, ok = self._shoot(x0)
        robot = self.robot
        for steps in ramps[1:]:
            if ok:
                break
            xk = CosseratSolver(_scaled(robot, 0.0), self.rtol, self.atol).initial_guess()
            for k in range(1, steps + 1):
                stage = CosseratSolver(_scaled(robot, k / steps), self.rtol, self.atol)
                xk, res, ok = stage._shoot(xk)
            x = xk
        converged = ok
        _, s, ys = self.integrate(x[:3], x[3:], dense=True)
        rots = ys[:, 3:12].reshape(-1, 3, 3)
        curv = []
        for si, y in zip(s, ys):
            inner = max(si - 1e-9, 0.0)  # the left limit: a termination at si still acts at si
            offsets, tensions = self._active(inner)
            piece = self.robot.piece_at(inner)
            curv.append(solve_curvature(y[3:12].reshape(3, 3).T @ y[15:18], piece, offsets, tensions))
        return CosseratSolution(s, ys[:, :3].copy(), rots, np.array(curv), res, converged)


def _scaled(robot: CosseratRobot, factor: float) -> CosseratRobot:
    """``robot`` with gravity, tensions and tip loads times ``factor`` (load continuation)."""
    import dataclasses

    return dataclasses.replace(
        robot,
        tendons=tuple(dataclasses.replace(t, tension=factor * t.tension) for t in robot.tendons),
        gravity=tuple(factor * g for g in robot.gravity),
        tip_force=tuple(factor * f for f in robot.tip_force),
        tip_moment=tuple(factor * m for m in robot.tip_moment),
    )


def constant_curvature_tip(kappa: float, length: float, phi: float = 0.0) -> Array:
    """Tip of a circular arc of curvature ``kappa`` bent toward direction ``phi`` in the xy plane."""
    if abs(kappa) < 1e-12:
        return np.array([0.0, 0.0, length])
    theta = kappa * length
    radial = (1.0 - math.cos(theta)) / kappa
    return np.array([radial * math.cos(phi), radial * math.sin(phi), math.sin(theta) / kappa])
