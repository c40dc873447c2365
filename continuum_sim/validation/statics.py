"""Static equilibrium and linearised stiffness of a MuJoCo model under world-fixed loads.

Equilibrium is where the net generalised force at rest vanishes,

    f(q) = qfrc_spring(q) − qfrc_gravity(q) + Σ_b J_b(q)ᵀ w_b = 0,

with w_b the world-frame wrenches of ``data.xfrc_applied`` (force at the body's centre
of mass, as MuJoCo applies it). A quasi-Newton root finder on f, with a finite-difference
Jacobian in the tangent space (``mj_integratePos``, so ball joints work too), converges
in a few iterations where simulating to rest takes thousands of steps. Only joint
springs, gravity and applied wrenches enter f: no contacts, constraints, actuators or
tendon springs (the validation models have none). World-fixed moments are not
conservative in 3-D, so there is no potential to minimise; the Jacobian is unsymmetric.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..configio import ConfigError, require_range

Array = NDArray[np.float64]


@dataclass(frozen=True)
class StaticSolverOptions:
    """Root-finder settings: relative step tolerance and the load-ramp retries."""

    tolerance: float = 1e-12
    ramps: tuple[int, ...] = (1, 4, 16)  # load steps tried in turn until every step converges

    def __post_init__(self) -> None:
        require_range("tolerance", self.tolerance, 0.0, 1e-3)
        if not self.ramps or any(isinstance(r, bool) or not isinstance(r, int) or not 1 <= r <= 1000 for r in self.ramps):
            raise ConfigError("ramps", f"must be a non-empty list of integers in [1, 1000] (got {self.ramps!r})")


@dataclass(frozen=True)
class StaticResult:
    converged: bool
    evaluations: int  # force evaluations over all load steps
    residual: float  # max |f| at the returned pose, N·m (or N)


class StaticSolver:
    """Solves ``f(q) = 0`` in place on ``data.qpos`` for given gravity and wrenches."""

    def __init__(self, model, data, options: StaticSolverOptions | None = None) -> None:
        import mujoco

        self._mj = mujoco
        self.model = model
        self.data = data
        self.options = options or StaticSolverOptions()
        self._bias = np.zeros(model.nv)
        self._qpos = np.zeros(model.nq)

    # ------------------------------------------------------------------ forces
    def net_force(self, qpos: Array, wrenches: Array, loaded: Array | None = None) -> Array:
        """f at ``qpos`` (velocity zero) under per-body world wrenches ``wrenches`` (nbody, 6).

        ``loaded`` lists the bodies with a non-zero wrench (found when not given).
        """
        mj, m, d = self._mj, self.model, self.data
        d.qpos[:] = qpos
        d.qvel[:] = 0.0
        mj.mj_kinematics(m, d)
        mj.mj_comPos(m, d)
        mj.mj_comVel(m, d)
        mj.mj_passive(m, d)
        mj.mj_rne(m, d, 0, self._bias)
        f = d.qfrc_passive - self._bias
        if loaded is None:
            loaded = np.flatnonzero(np.any(wrenches != 0.0, axis=1))  # type: ignore[assignment]
        for body in loaded:  # type: ignore[union-attr]
            mj.mj_applyFT(m, d, wrenches[body, :3], wrenches[body, 3:], d.xipos[body], int(body), f)
        return f

    def jacobian(self, qpos: Array, wrenches: Array, step: float = 1e-7) -> Array:
        """∂f/∂q (nv × nv) by forward differences along each tangent direction."""
        m = self.model
        f0 = self.net_force(qpos, wrenches)
        jac = np.empty((m.nv, m.nv))
        q = np.empty(m.nq)
        basis = np.eye(m.nv)
        for j in range(m.nv):
            q[:] = qpos
            self._mj.mj_integratePos(m, q, basis[j], step)
            jac[:, j] = (self.net_force(q, wrenches) - f0) / step
        return jac

    # ------------------------------------------------------------------ solve
    def solve(self, gravity: Array, wrenches: Array) -> StaticResult:
        """Equilibrium under ``gravity`` (m/s²) and ``wrenches`` (nbody, 6), from data.qpos.

        MINPACK's hybrid Powell method (``scipy.optimize.root``, ``hybr``): one
        finite-difference Jacobian, then rank-one updates, so a case costs about nv + 15
        force evaluations. The unknowns are tangent-space offsets from the start pose
        (ball joints included). When the full load in one step fails, the load is ramped
        in more steps from the start pose. On return ``model.opt.gravity`` and
        ``data.xfrc_applied`` hold the full loads and the kinematics are evaluated.
        """
        m, d = self.model, self.data
        gravity = np.asarray(gravity, dtype=float)
        wrenches = np.asarray(wrenches, dtype=float)
        start = d.qpos.copy()
        evaluations = 0
        for steps in self.options.ramps:
            qpos, converged = start.copy(), True
            for step in range(1, steps + 1):
                scale = step / steps
                m.opt.gravity[:] = scale * gravity
                qpos, count, ok = self._root(qpos, scale * wrenches)
                evaluations += count
                converged &= ok
            if converged:
                break
        f = self.net_force(qpos, wrenches)
        d.xfrc_applied[:] = wrenches
        return StaticResult(bool(converged), evaluations, float(np.max(np.abs(f), initial=0.0)))

    def _root(self, start: Array, wrenches: Array) -> tuple[Array, int, bool]:
        from scipy.optimize import root

        loaded = np.flatnonzero(np.any(wrenches != 0.0, axis=1))
        m, q = self.model, self._qpos

        def pose(x: Array) -> Array:
            q[:] = start
            self._mj.mj_integratePos(m, q, x, 1.0)
            return q

        sol = root(
            lambda x: self.net_force(pose(x), wrenches, loaded),  # type: ignore[arg-type]
            np.zeros(m.nv),
            method="hybr",
            options={"xtol": self.options.tolerance},
        )
        # MINPACK may stop with "no progress" at a residual already at round-off (seen on
        # stiff segments under large loads): accept a residual below 1e-12 (N, N·m).
        ok = bool(sol.success) or float(np.max(np.abs(sol.fun), initial=0.0)) <= 1e-12
        return pose(sol.x).copy(), int(sol.nfev), ok


def linear_natural_frequencies(model, data, count: int = 1) -> Array:
    """Lowest natural frequencies (Hz) of the model linearised at ``data.qpos``, at rest.

    Solves K v = ω² M v with M from ``mj_fullM`` and K = −∂f/∂q, the static solver's
    stiffness (joint springs, plus gravity's when ``model.opt.gravity`` is on), undamped.
    """
    import mujoco
    from scipy.linalg import eigh

    qpos = data.qpos.copy()
    solver = StaticSolver(model, data)
    stiffness = -solver.jacobian(qpos, np.zeros((model.nbody, 6)))
    data.qpos[:] = qpos
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    omega2 = eigh(0.5 * (stiffness + stiffness.T), mass, eigvals_only=True)
    return np.sqrt(np.clip(omega2[:count], 0.0, None)) / (2.0 * np.pi)
