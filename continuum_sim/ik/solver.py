"""The IK solver: projected Levenberg-Marquardt, a chord fast path for warm starts, cold-start seeds.

Projected Levenberg-Marquardt with the analytic Jacobian (``kinematics_kernels.ArmPose``) and damping
``λ = μ‖r‖²``, which turns into plain Gauss-Newton near a zero-residual solution
(quadratic convergence, hence errors ~1e-13 after a few steps). Cold starts try a fixed
table of seed configurations ordered by how close their tool pose is to the target
(deterministic); warm starts begin at ``q0``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from .. import kinematics as kin
from .options import Array
from .problem import IKProblem

# LAPACK's Cholesky routines (a tenth of np.linalg.solve's call overhead on 6×6), loaded by
# the first solve: importing scipy costs ~0.3 s, which loading a configuration should not pay.
_dposv: Any = None
_dpotrf: Any = None
_dpotrs: Any = None


def _load_lapack() -> None:
    global _dposv, _dpotrf, _dpotrs
    if _dposv is None:
        from scipy.linalg.lapack import dposv, dpotrf, dpotrs

        _dposv, _dpotrf, _dpotrs = dposv, dpotrf, dpotrs


class Iterate(NamedTuple):
    """Where a Levenberg-Marquardt run ended (``IKSolver._lm``)."""

    x: list[float]
    position_error: float
    orientation_error: float
    iterations: int
    rotation: list[float]
    position: list[float]


class ChordIterate(NamedTuple):
    """Where the warm-start chord iteration ended (``IKSolver._chord``)."""

    x: list[float]
    residual: list[float]
    jacobian: Any  # array, or None
    position_error: float
    orientation_error: float
    rotation: list[float]
    position: list[float]
    iterations: int
    converged: bool


class Solution(NamedTuple):
    """``IKSolver.solve``'s answer in solver variables (``solve_ik`` wraps it in an ``IKResult``)."""

    x: list[float]
    position_error: float
    orientation_error: float
    iterations: int
    success: bool
    message: str
    rotation: list[float]
    position: list[float]


class IKSolver(IKProblem):
    """IK for one arm, one tool, one mode, in the arm base frame; reusable across targets.

    ``solve_ik`` caches these per (geometry, mode, tool, options); build one directly to
    solve many targets without even the cache lookup.
    """

    # Set per instance on first use: the cold-start seed table (``seed_table``), and the last
    # solution as (q, x), which ``solve_ik`` warm-started from it reuses instead of recomputing
    # x from q. Not thread-safe; one solver per thread.
    _seeds: tuple[Array, Array, Array] | None = None
    last_solution: tuple[Array, list[float]] | None = None

    # ---------------------------------------------------------------- LM core
    TAU = 1e-10  # initial damping relative to the largest diagonal entry of JᵀJ

    def _lm(self, x0, tgt, max_iterations: int, max_step: float) -> Iterate:
        """Projected Levenberg-Marquardt from ``x0``.

        Damping starts tiny (a Gauss-Newton step) and adapts by the gain ratio (Nielsen's
        rule); the floor ``1e-12·tr(JᵀJ)`` keeps the step out of the null space in the
        redundant ``axis`` mode. Each section's step is capped at ``max_step``. Written
        for one small problem at a time: few numpy calls per iteration.
        """
        opts = self.options
        stop_p = 1e-2 * opts.position_tolerance  # quadratic convergence: one step past 1e-2·tol is ~1e-15
        stop_o = 1e-2 * opts.orientation_tolerance
        x = self.project([float(v) for v in x0])
        r, J, ep, eo, R, p = self.evaluate(x, tgt)
        cost = sum(v * v for v in r)
        n = self.n_vars
        S = self.S
        planar = self.phase == "planar"
        dposv = _dposv
        diag = self._diag
        lam = -1.0
        nu = 2.0
        scale = floor = 0.0
        its = 0
        while its < max_iterations and not (ep <= stop_p and eo <= stop_o):
            its += 1
            JT = J.T
            A = JT.dot(J)
            g = JT.dot(r)
            if lam < 0.0:
                scale = float(A.trace()) / n
                lam = self.TAU * scale
                floor = 1e-12 * scale + 1e-300
            damping = lam + floor
            A[diag] += damping
            _, sol, info = dposv(A, g)
            if info != 0:
                break
            delta = sol.tolist()  # the step is -sol
            # Trust region: no section's bending coordinates move more than max_step.
            if planar:
                biggest = max(abs(d) for d in delta)
            else:
                biggest = math.sqrt(max(delta[2 * k] ** 2 + delta[2 * k + 1] ** 2 for k in range(S)))
            if biggest < 1e-16:
                break
            clipped = biggest > max_step
            if clipped:
                f = max_step / biggest
                delta = [d * f for d in delta]
            x_new = self.project([xi - di for xi, di in zip(x, delta)])
            r_new, J_new, ep_new, eo_new, R_new, p_new = self.evaluate(x_new, tgt)
            cost_new = sum(v * v for v in r_new)
            if cost_new < cost:
                # Gain ratio: actual decrease over the linear model's. For the unclipped
                # step -sol of (A + λI) sol = g the model decrease is gᵀsol + λ|sol|².
                if clipped:
                    Jd = J.dot(delta)
                    predicted = 2.0 * float(g.dot(delta)) - float(Jd.dot(Jd))
                else:
                    gl = g.tolist()
                    predicted = sum(a * b for a, b in zip(gl, delta)) + damping * sum(d * d for d in delta)
                rho = (cost - cost_new) / predicted if predicted > 0.0 else 1.0
                x, r, J, ep, eo, R, p, cost = x_new, r_new, J_new, ep_new, eo_new, R_new, p_new, cost_new
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
            else:
                lam = max(lam, floor) * nu
                nu *= 2.0
                if lam > 1e10 * scale:
                    break
        return Iterate(x, ep, eo, its, R, p)

    CHORD_ITERATIONS = 8
    CHORD_MIN_GAIN = 0.3  # a chord step must shrink the residual norm at least this much

    def _chord(self, x0, tgt, max_step: float) -> ChordIterate:
        """Warm-start fast path: Newton's chord method (Jacobian frozen at the start).

        From a nearby start the frozen Jacobian is accurate to O(distance), so each step
        gains about as many digits as the start was close, at the price of an FK without
        derivatives (~3× cheaper than FK with the Jacobian) and a triangular solve.
        Returns a ``ChordIterate``; when a step does not shrink the
        residual by ``CHORD_MIN_GAIN`` the caller continues with full LM from the result.
        """
        opts = self.options
        stop_p = 1e-2 * opts.position_tolerance
        stop_o = 1e-2 * opts.orientation_tolerance
        x = self.project([float(v) for v in x0])
        r, J, ep, eo, R, p = self.evaluate(x, tgt)
        its = 0
        if ep <= stop_p and eo <= stop_o:
            return ChordIterate(x, r, J, ep, eo, R, p, its, True)
        JT = J.T
        A = JT.dot(J)
        scale = float(A.trace()) / self.n_vars
        A[self._diag] += 1e-12 * scale + 1e-300
        c, info = _dpotrf(A)
        if info != 0:
            return ChordIterate(x, r, J, ep, eo, R, p, its, False)
        norm = math.sqrt(sum(v * v for v in r))
        J0 = J
        while its < self.CHORD_ITERATIONS:
            its += 1
            step, info = _dpotrs(c, JT.dot(r))
            if info != 0:
                break
            delta = step.tolist()
            if max(abs(d) for d in delta) > max_step:
                break
            x_new = self.project([xi - di for xi, di in zip(x, delta)])
            r_new, _, ep_new, eo_new, R_new, p_new = self.evaluate(x_new, tgt, derivatives=False)
            norm_new = math.sqrt(sum(v * v for v in r_new))
            if norm_new > self.CHORD_MIN_GAIN * norm:
                if norm_new < norm:
                    x, r, ep, eo, R, p, norm = x_new, r_new, ep_new, eo_new, R_new, p_new, norm_new
                    J0 = None  # J no longer belongs to x
                break
            x, r, ep, eo, R, p, norm = x_new, r_new, ep_new, eo_new, R_new, p_new, norm_new
            J0 = None
            if ep <= stop_p and eo <= stop_o:
                return ChordIterate(x, r, None, ep, eo, R, p, its, True)
        return ChordIterate(x, r, J0, ep, eo, R, p, its, False)

    # ---------------------------------------------------------------- seeds
    def seed_table(self) -> tuple[Array, Array, Array]:
        """Fixed cold-start configurations (solver variables), their tool positions and rotations."""
        if self._seeds is None:
            rng = np.random.default_rng(self.options.seed)
            N = self.options.seed_table_size
            bounds = np.array(self.bounds)
            if self.phase == "planar":
                X = rng.uniform(-1.0, 1.0, (N, self.S)) * bounds
                X[0] = 0.0
                W = np.empty((N, 2 * self.S))
                W[:, 0::2] = X * self._cpsi
                W[:, 1::2] = X * self._spsi
            else:
                theta = rng.uniform(0.0, 1.0, (N, self.S)) * bounds
                phi = rng.uniform(-np.pi, np.pi, (N, self.S))
                X = np.empty((N, 2 * self.S))
                X[:, 0::2] = theta * np.cos(phi)
                X[:, 1::2] = theta * np.sin(phi)
                X[0] = 0.0
                W = X
            T = kin.forward_kinematics_bending(self.geometry, W, tool_length=self.tool_length)
            self._seeds = (X, T[:, :3, 3], T[:, :3, :3])
        return self._seeds

    def _seed_order(self, target: Array) -> NDArray[np.intp]:
        X, P, R = self.seed_table()
        k1, k2 = self.options.position_weight, self.options.orientation_weight
        score = k1**2 * np.sum((P - target[:3, 3]) ** 2, axis=1)
        if self.orientation == "full":
            score += k2**2 * (3.0 - np.einsum("nij,ij->n", R, target[:3, :3]))
        else:
            score += k2**2 * 2.0 * (1.0 - R[:, :, 2] @ target[:3, 2])
        return np.argsort(score, kind="stable")

    # ---------------------------------------------------------------- public
    def solve(self, target: Array, x0=None, *, fallback: bool = True, max_step: float | None = None,
              max_iterations: int | None = None) -> Solution:
        """Solve for a validated (4, 4) target in the arm frame.

        With ``x0`` the solve is warm-started there; ``fallback`` then allows cold starts
        if the warm start fails.
        """
        _load_lapack()
        tgt = self._prepare(target)
        opts = self.options
        step = opts.max_step_rad if max_step is None else max_step
        iters = opts.max_iterations if max_iterations is None else max_iterations
        total = 0
        best = None
        if x0 is not None:
            x, _, _, ep, eo, R, p, its, done = self._chord(x0, tgt, step)
            total += its
            if not done:
                x, ep, eo, its, R, p = self._lm(x, tgt, max(iters - its, 1), step)
                total += its
            if self._ok(ep, eo):
                return Solution(x, ep, eo, total, True, "converged (warm start)", R, p)
            best = (self._weighted(ep, eo), x, ep, eo, R, p)
            if not fallback:
                return Solution(x, ep, eo, total, False, self._failure_message(target, ep, eo), R, p)
        X = self.seed_table()[0]
        for idx in self._seed_order(target)[: opts.n_starts]:
            x, ep, eo, its, R, p = self._lm(X[idx], tgt, iters, step)
            total += its
            if self._ok(ep, eo):
                return Solution(x, ep, eo, total, True, "converged (cold start)", R, p)
            cand = (self._weighted(ep, eo), x, ep, eo, R, p)
            if best is None or cand[0] < best[0]:
                best = cand
        assert best is not None  # n_starts >= 1 (IKOptions)
        _, x, ep, eo, R, p = best
        return Solution(x, ep, eo, total, False, self._failure_message(target, ep, eo), R, p)

    def cold_solutions(self, target: Array, n_starts: int) -> Iterator[list[float]]:
        """The converged solutions (solver variables) of the first ``n_starts`` cold starts, best seeds first.

        For a caller that picks a solution branch itself (the planner: the one nearest a
        reference shape) rather than the first that converges.
        """
        _load_lapack()
        tgt = self._prepare(target)
        X = self.seed_table()[0]
        for idx in self._seed_order(target)[:n_starts]:
            x, ep, eo, _, _, _ = self._lm(X[idx], tgt, self.options.max_iterations, self.options.max_step_rad)
            if self._ok(ep, eo):
                yield x

    def _failure_message(self, target: Array, ep: float, eo: float) -> str:
        distance = float(np.linalg.norm(target[:3, 3]))
        where = ""
        if distance > self.reach:
            where = f"outside the workspace: target is {distance:.4f} m from the arm base, beyond the reach {self.reach:.4f} m; "
        return (
            f"{where}unreachable: best residual position error {ep:.3e} m, orientation error {eo:.3e} rad "
            f"(tolerances {self.options.position_tolerance:g} m, {self.options.orientation_tolerance:g} rad)"
        )
