"""Geometrically nonlinear moment–rotation of one flexure segment: a discrete Cosserat rod per leaf.

Shares no formula with ``continuum_sim.model.stiffness`` (the linear segment stiffness);
``continuum_sim.validation.flexure_nonlinear`` checks it against textbook limits (Euler
load, Bisshopp–Drucker's large-deflection cantilever, the small-rotation beam stiffness)
and compares it with the linear model. Each leaf is a geometrically exact rod
(Simo–Reissner: extension, two shears, two bendings and torsion, every strain measured in
the rotated frame, so finite rotations, axial–bending coupling and buckling follow from
the energy), cut into ``n`` two-node elements evaluated at their midpoints (one-point
integration: no shear locking). Equilibrium of the free nodes: Newton's method on the
energy. A reaction is the derivative of the minimised energy with respect to the imposed
coordinate (envelope theorem: the partial derivative at equilibrium, central differences).

A segment (docs/model.md, "Flexures beyond linear"): the lower disk is fixed, the upper
disk turns by a rotation vector s = (s_x, s_y, 0) about the central joint at mid-gap,
and each leaf's ends are clamped in the disks; the leaves are independent given s, so
the segment energy is the sum of the three leaf energies and the moment that holds the
disk is M = ∂U/∂s. A stress-free bow of 1/2000 of the free length (the first
clamped–clamped buckling shape, radial) seeds the buckling of a compressed leaf.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from ..configio import require_int, require_positive, require_range

if TYPE_CHECKING:
    from ..geometry import ArmGeometry, SectionGeometry


@dataclass(frozen=True)
class LeafSection:
    """A rectangular leaf: ``width`` tangential, ``thickness`` radial, material E and ν."""

    width: float
    thickness: float
    youngs_modulus: float
    poisson_ratio: float

    def __post_init__(self) -> None:
        require_positive("width", self.width)
        require_positive("thickness", self.thickness)
        require_positive("youngs_modulus", self.youngs_modulus)
        require_range("poisson_ratio", self.poisson_ratio, -1.0, 0.5, high_inclusive=False)

    @property
    def shear_modulus(self) -> float:
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def area(self) -> float:
        return self.width * self.thickness

    @property
    def i_radial_axis(self) -> float:
        """Second moment about the radial axis (bending that deflects the leaf tangentially)."""
        return self.thickness * self.width**3 / 12.0

    @property
    def i_tangential_axis(self) -> float:
        """Second moment about the tangential axis (the weak axis: the leaf deflects radially)."""
        return self.width * self.thickness**3 / 12.0

    @property
    def torsion_constant(self) -> float:
        """St Venant constant of the rectangle, exact series (Timoshenko & Goodier §109)."""
        big, small = max(self.width, self.thickness), min(self.width, self.thickness)
        total = sum(math.tanh(n * math.pi * big / (2.0 * small)) / n**5 for n in range(1, 100, 2))
        return big * small**3 / 3.0 * (1.0 - 192.0 / math.pi**5 * (small / big) * total)

    @property
    def shear_coefficient(self) -> float:
        """Cowper's shear coefficient of a rectangle, 10(1+ν)/(12+11ν)."""
        nu = self.poisson_ratio
        return 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)


E_Z = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Rod:
    """A straight (or slightly bowed) rod of ``n`` elements along z from ``start``; its material ``section``.

    Local axes: x radial (the leaf's thickness, weak bending about y), y tangential (its
    width). ``bow`` is a stress-free radial offset v(z) = bow·(1 − cos 2πz/L)/2.
    """

    section: LeafSection
    length: float
    n: int = 16
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    bow: float = 0.0

    def __post_init__(self) -> None:
        require_positive("length", self.length)
        require_int("n", self.n, 2, 400)
        require_range("bow", abs(self.bow), 0.0, 0.1 * self.length, low_inclusive=True)

    @property
    def h(self) -> float:
        return self.length / self.n

    def reference(self) -> np.ndarray:
        """(n+1, 6) stress-free nodes: position, rotation vector (tangent-aligned frame)."""
        z = np.linspace(0.0, self.length, self.n + 1)
        k = 2.0 * math.pi / self.length
        x = 0.5 * self.bow * (1.0 - np.cos(k * z))
        slope = 0.5 * self.bow * k * np.sin(k * z)
        q = np.zeros((self.n + 1, 6))
        q[:, :3] = np.asarray(self.start) + np.column_stack([x, np.zeros_like(z), z])
        q[:, 4] = np.arctan(slope)  # rotation about y tilts the z axis toward +x
        return q

    def weights(self) -> np.ndarray:
        """(6,) sqrt(h·C) for (γ_x, γ_y, ε, κ_x, κ_y, κ_z), Cowper shear coefficient."""
        s = self.section
        ga = s.shear_coefficient * s.shear_modulus * s.area
        c = np.array([ga, ga, s.youngs_modulus * s.area, s.youngs_modulus * s.i_radial_axis,
                      s.youngs_modulus * s.i_tangential_axis, s.shear_modulus * s.torsion_constant])
        scale = np.array([self.h, self.h, self.h, 1.0 / self.h, 1.0 / self.h, 1.0 / self.h])
        return np.sqrt(c * scale)

    def strains(self, q: np.ndarray) -> np.ndarray:
        """(n, 6) element strains: Γ = R_midᵀ Δx/h − e_z and K·h = log(R_iᵀ R_i+1) (the latter times h)."""
        return element_strains(q[:-1], q[1:], self.h)


def _rotations(v: np.ndarray) -> np.ndarray:
    """(m, 3, 3) rotation matrices of rotation vectors (m, 3), Rodrigues."""
    theta = np.sqrt(np.einsum("ij,ij->i", v, v))
    small = theta < 1e-6
    t = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6.0, np.sin(t) / t)
    b = np.where(small, 0.5 - theta**2 / 24.0, (1.0 - np.cos(t)) / (t * t))
    k = np.zeros((len(v), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    return np.eye(3) + a[:, None, None] * k + b[:, None, None] * (k @ k)


def _log(r: np.ndarray) -> np.ndarray:
    """(m, 3) rotation vectors of rotation matrices (m, 3, 3), angles below π."""
    vee = 0.5 * np.stack([r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], axis=1)
    sin = np.sqrt(np.einsum("ij,ij->i", vee, vee))
    cos = 0.5 * (np.trace(r, axis1=1, axis2=2) - 1.0)
    theta = np.arctan2(sin, cos)
    factor = np.where(sin < 1e-8, 1.0 + theta**2 / 6.0, theta / np.where(sin < 1e-8, 1.0, sin))
    return factor[:, None] * vee


def element_strains(a: np.ndarray, b: np.ndarray, h: float) -> np.ndarray:
    """(m, 6) strains of elements from node a (m, 6) to node b (m, 6): (Γ, K·h), Simo–Reissner at the midpoint."""
    ra, rb = _rotations(a[:, 3:]), _rotations(b[:, 3:])
    kh = _log(np.einsum("mji,mjk->mik", ra, rb))
    mid = ra @ _rotations(0.5 * kh)
    gamma = np.einsum("mji,mj->mi", mid, (b[:, :3] - a[:, :3]) / h) - E_Z
    return np.hstack([gamma, kh])


class RodProblem:
    """Equilibrium of a ``Rod`` with some node coordinates imposed (``fixed`` mask) and the rest free.

    Newton's method on the energy with its exact gradient and Hessian up to finite-difference
    error: both assembled from element energies differentiated by central differences, all
    elements and perturbations in one vectorised evaluation; a shift keeps each Newton step a
    descent direction where the Hessian is indefinite.
    """

    def __init__(self, rod: Rod, fixed: np.ndarray) -> None:
        self.rod = rod
        self.fixed = np.asarray(fixed, dtype=bool).reshape(rod.n + 1, 6)
        self.free = ~self.fixed.ravel()
        self.w2 = rod.weights() ** 2
        self.s0 = rod.strains(rod.reference())
        self.steps = np.array([1e-3 * rod.h] * 3 + [1e-4] * 3)

    def element_energy(self, ya: np.ndarray, yb: np.ndarray, s0: np.ndarray) -> np.ndarray:
        strain = element_strains(ya, yb, self.rod.h) - s0
        return 0.5 * np.einsum("mi,i->m", strain * strain, self.w2)

    def energy(self, q: np.ndarray) -> float:
        return float(self.element_energy(q[:-1], q[1:], self.s0).sum())

    def gradient_hessian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Full gradient (6(n+1),) and Hessian (6(n+1), 6(n+1)) of the energy at ``q``."""
        n = self.rod.n
        y = np.hstack([q[:-1], q[1:]])  # (n, 12)
        step = np.concatenate([self.steps, self.steps])
        # central differences for the gradient; forward differences of the energy for the
        # Hessian (second order where it matters: the gradient fixes the equilibrium)
        eye = np.diag(step)
        offsets = [np.zeros(12), *eye, *(-eye)]
        pairs = [(i, j) for i in range(12) for j in range(i + 1, 12)]
        offsets += [eye[i] + eye[j] for i, j in pairs]
        off = np.array(offsets)  # (k, 12)
        batch = (y[None, :, :] + off[:, None, :]).reshape(-1, 12)
        e = self.element_energy(batch[:, :6], batch[:, 6:], np.tile(self.s0, (len(off), 1))).reshape(len(off), n)
        e0, ep, em = e[0], e[1:13], e[13:25]
        grad_e = ((ep - em) / (2.0 * step[:, None])).T
        hess_e = np.zeros((n, 12, 12))
        for k, (i, j) in enumerate(pairs):
            hess_e[:, i, j] = hess_e[:, j, i] = (e[25 + k] - ep[i] - ep[j] + e0) / (step[i] * step[j])
        for i in range(12):
            hess_e[:, i, i] = (ep[i] - 2.0 * e0 + em[i]) / step[i] ** 2
        size = 6 * (n + 1)
        grad = np.zeros(size)
        hess = np.zeros((size, size))
        for m in range(n):
            sl = slice(6 * m, 6 * m + 12)
            grad[sl] += grad_e[m]
            hess[sl, sl] += hess_e[m]
        return grad, hess

    def solve(self, q: np.ndarray, tol: float = 1e-10, max_iter: int = 60) -> np.ndarray:
        """``q`` with its free coordinates at the energy minimum reached from ``q`` (a local one)."""
        q = np.array(q, dtype=float)
        free = self.free
        scale = np.tile(self.steps, self.rod.n + 1)[free] / self.steps[3]  # metres vs radians
        for _ in range(max_iter):
            grad, hess = self.gradient_hessian(q)
            g, h = grad[free], hess[np.ix_(free, free)]
            shift = 0.0
            while True:
                try:
                    chol = np.linalg.cholesky(h + shift * np.diag(np.diag(h)))
                    break
                except np.linalg.LinAlgError:
                    shift = max(2.0 * shift, 1e-6)
            dx = -np.linalg.solve(chol.T, np.linalg.solve(chol, g))
            e0, t = self.energy(q), 1.0
            while t > 1e-6:
                flat = q.copy().ravel()
                flat[free] += t * dx
                trial = flat.reshape(q.shape)
                if self.energy(trial) <= e0 + 1e-4 * t * float(g @ dx) + 1e-18:
                    break
                t *= 0.5
            q = trial
            if np.max(np.abs(t * dx) / scale) < tol:
                break
        return q

    def reaction(self, q: np.ndarray, direction: np.ndarray, step: float = 1e-8) -> float:
        """dU/dλ for the imposed motion q + λ·direction (free coordinates held at equilibrium)."""
        return (self.energy(q + step * direction) - self.energy(q - step * direction)) / (2.0 * step)


# =========================================================================== segment
@dataclass(frozen=True)
class FlexureSegment:
    """Three leaves (width tangential, thickness radial) between two disks, a central joint at mid-gap."""

    leaf: LeafSection
    free_length: float
    leaf_radius: float
    leaf_angles_deg: tuple[float, ...] = (0.0, 120.0, 240.0)
    elements: int = 16
    bow_fraction: float = 5e-4

    def __post_init__(self) -> None:
        require_positive("free_length", self.free_length)
        require_range("leaf_radius", self.leaf_radius, 0.0, 1.0, low_inclusive=True)
        require_int("elements", self.elements, 4, 400)

    def rod(self) -> Rod:
        g = self.free_length
        return Rod(self.leaf, g, self.elements, start=(self.leaf_radius, 0.0, -0.5 * g), bow=self.bow_fraction * g)

    def leaf_curve(self, theta: np.ndarray, psi: float) -> np.ndarray:
        """(len(theta), 2) ∂U_leaf/∂s (N·m) of the leaf at angle 0 for s = θ·(cos ψ, sin ψ, 0), θ increasing from 0.

        Each solve starts from the previous one (a continuation along θ).
        """
        rod = self.rod()
        fixed = np.zeros((rod.n + 1, 6), dtype=bool)
        fixed[[0, -1]] = True
        problem = RodProblem(rod, fixed)
        ref = rod.reference()
        top = ref[-1, :3].copy()
        q = ref.copy()
        axis = np.array([math.cos(psi), math.sin(psi), 0.0])
        out = np.zeros((len(theta), 2))

        def place(qq: np.ndarray, s: np.ndarray) -> np.ndarray:
            qq = qq.copy()
            r = Rotation.from_rotvec(s)
            qq[-1, :3] = r.apply(top)
            qq[-1, 3:] = (r * Rotation.from_rotvec(ref[-1, 3:])).as_rotvec()
            return qq

        step = 1e-7
        for i, th in enumerate(np.asarray(theta, dtype=float)):
            guess = place(q, th * axis)
            if i > 0:  # carry the interior along the rigid motion increment (better start)
                dr = Rotation.from_rotvec(th * axis) * Rotation.from_rotvec(float(theta[i - 1]) * axis).inv()
                guess[1:-1, :3] = dr.apply(q[1:-1, :3])
                guess[1:-1, 3:] = (dr * Rotation.from_rotvec(q[1:-1, 3:])).as_rotvec()
            q = problem.solve(guess)
            s = th * axis
            for j in range(2):
                ds = np.zeros(3)
                ds[j] = step
                out[i, j] = (problem.energy(place(q, s + ds)) - problem.energy(place(q, s - ds))) / (2.0 * step)
        return out

    def moment_curve(self, theta: np.ndarray, phi: float) -> np.ndarray:
        """(len(theta), 2) segment moment M = ∂U/∂s (N·m) along s = θ·(cos φ, sin φ, 0)."""
        total = np.zeros((len(theta), 2))
        for alpha in np.radians(self.leaf_angles_deg):
            c, s = math.cos(alpha), math.sin(alpha)
            local = self.leaf_curve(theta, phi - alpha)
            total[:, 0] += c * local[:, 0] - s * local[:, 1]
            total[:, 1] += s * local[:, 0] + c * local[:, 1]
        return total


def section_segment(geometry: ArmGeometry, section: SectionGeometry, elements: int = 16) -> FlexureSegment:
    """The nonlinear model of one physical segment of ``section`` (leaf fields, material)."""
    leaf = LeafSection(section.hinge_width, section.hinge_thickness, geometry.material.youngs_modulus,
                       geometry.material.poisson_ratio)
    return FlexureSegment(leaf, section.leaf_length(geometry.disk_thickness), section.leaf_radius,
                          tuple(section.leaf_angles_deg), elements, geometry.leaf_bow_fraction)


TABLE_VERSION = 1  # bump when the solver or the grid changes: invalidates the on-disk cache


SHIPPED = Path(__file__).resolve().parent.parent / "data" / "flexure"  # the default arm's tables (scripts/flexure_tables.py)


def table_name(segment: FlexureSegment, theta_max: float, n_theta: int, n_psi: int) -> str:
    """The file name of a leaf table: a hash of every input."""
    key = repr((TABLE_VERSION, segment, float(theta_max), int(n_theta), int(n_psi))).encode()
    return f"{hashlib.sha256(key).hexdigest()[:24]}.npz"


def _cache_dir() -> Path:
    root = os.environ.get("CONTINUUM_SIM_CACHE") or os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "continuum_sim")
    return Path(root) / "flexure"


@lru_cache(maxsize=32)
def leaf_table(segment: FlexureSegment, theta_max: float, n_theta: int, n_psi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(θ grid, ψ grid over [−π/2, π/2], (n_psi, n_theta, 2) leaf moments ∂U/∂s): one leaf, polar grid of s.

    The leaf is symmetric about its radial plane (y → −y), under which a rotation vector
    (s_x, s_y) becomes (−s_x, s_y): ψ and π − ψ give mirrored moments, so half the circle
    suffices. Cached in memory and on disk (``$CONTINUUM_SIM_CACHE`` or
    ``~/.cache/continuum_sim/flexure``), keyed by every input; a cold table takes seconds.
    """
    name = table_name(segment, theta_max, n_theta, n_psi)
    path = _cache_dir() / name
    theta = np.linspace(0.0, theta_max, n_theta)
    psi = np.linspace(-0.5 * math.pi, 0.5 * math.pi, n_psi)
    for stored_path in (SHIPPED / name, path):
        try:
            with np.load(stored_path) as stored:
                table = stored["table"]
            if table.shape == (n_psi, n_theta, 2):
                return theta, psi, table
        except (OSError, KeyError, ValueError):
            pass
    table = np.stack([segment.leaf_curve(theta, p) for p in psi])
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, table=table)
        os.replace(tmp, path)
    except OSError:
        pass  # a read-only home: the table is recomputed next process
    return theta, psi, table
