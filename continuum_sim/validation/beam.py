"""Closed-form cantilever results the backbone model is checked against (SPEC §10).

Cantilever of length L and bending rigidity EI, clamped at s = 0:

* tip force F (small): deflection F·L³/(3EI), slope F·L²/(2EI) (Euler–Bernoulli);
* tip moment M: uniform curvature M/EI, so at any size the rod is a circular arc of
  radius EI/M and angle M·L/EI (the elastica under a pure end moment), small-deflection
  tip offset M·L²/(2EI);
* first bending mode: ω = β₁²·sqrt(EI/(μL⁴)), β₁ = 1.875104 (μ = mass per length),
  generalised to a tip mass, a tip rotary inertia and distributed rotary inertia
  (Rayleigh beam), which a chain of disks has and a thin beam does not.

A chain of n links with joints half-way between nodes (joint i at s = (i − ½)h) bends
like the beam up to O(1/n²): a tip moment is reproduced exactly (uniform curvature), and
under a tip force the joints sample the moment by the midpoint rule, so the tip moves
F·L³/(3EI)·(1 − 1/(4n²)) (``chain_tip_deflection``).
"""

from __future__ import annotations

import math

import numpy as np

BETA1 = 1.8751040687119611  # first root of 1 + cos β cosh β = 0


def tip_deflection_force(force: float, length: float, ei: float) -> float:
    """Tip deflection (m) of a cantilever under a small transverse tip force."""
    return force * length**3 / (3.0 * ei)


def tip_slope_force(force: float, length: float, ei: float) -> float:
    """Tip rotation (rad) under a small transverse tip force."""
    return force * length**2 / (2.0 * ei)


def chain_tip_deflection(force: float, length: float, ei: float, n: int) -> float:
    """Tip deflection of the n-joint chain of stiffness n·EI/L under a small tip force.

    Σ F (L − s_i)² / k over joints at s_i = (i − ½)L/n, summed in closed form.
    """
    return tip_deflection_force(force, length, ei) * (1.0 - 1.0 / (4.0 * n * n))


def tip_deflection_moment(moment: float, length: float, ei: float) -> float:
    """Tip deflection (m) under a small tip moment."""
    return moment * length**2 / (2.0 * ei)


def arc_angle(moment: float, length: float, ei: float) -> float:
    """Bend angle (rad) of the elastica under an end moment: exact, any size."""
    return moment * length / ei


def arc_point(moment: float, ei: float, s: float | np.ndarray) -> np.ndarray:
    """(along, across) coordinates of the arc at arc length ``s`` from the clamp."""
    kappa = moment / ei
    s = np.asarray(s, dtype=float)
    along = s * np.sinc(kappa * s / np.pi)
    across = kappa * s * s / 2.0 * np.sinc(kappa * s / (2.0 * np.pi)) ** 2  # (1 − cos κs)/κ
    return np.stack([along, across], axis=-1)


def cantilever_first_frequency(
    ei: float,
    mass_per_length: float,
    length: float,
    tip_mass: float = 0.0,
    tip_inertia: float = 0.0,
    rotary_inertia_per_length: float = 0.0,
) -> float:
    """First bending natural frequency (Hz) of a uniform cantilever.

    With the defaults this is β₁²·sqrt(EI/(μL⁴))/(2π). Otherwise it is the exact first
    root of the Rayleigh-beam equation EI w'''' + ω²ρI w'' − ω²μ w = 0 (ρI: rotary
    inertia per length) with a point mass and rotary inertia at the free end: a 4 × 4
    boundary determinant in ω, bracketed on a grid and refined by Brent's method.
    """
    from scipy.optimize import brentq

    mu, r, mt, jt = mass_per_length, rotary_inertia_per_length, tip_mass, tip_inertia
    omega_eb = BETA1**2 * math.sqrt(ei / (mu * length**4))
    if mt == 0.0 and jt == 0.0 and r == 0.0:
        return omega_eb / (2.0 * math.pi)

    def determinant(omega: float) -> float:
        w2 = omega * omega
        disc = math.sqrt((w2 * r) ** 2 + 4.0 * ei * w2 * mu)
        a = math.sqrt((disc - w2 * r) / (2.0 * ei))  # w ~ cosh/sinh(a s)
        b = math.sqrt((disc + w2 * r) / (2.0 * ei))  # w ~ cos/sin(b s)
        ch, sh = math.cosh(a * length), math.sinh(a * length)
        c, s = math.cos(b * length), math.sin(b * length)
        # columns: cosh, sinh, cos, sin; value, slope, curvature, third derivative at L
        value = np.array([ch, sh, c, s])
        slope = np.array([a * sh, a * ch, -b * s, b * c])
        curv = np.array([a * a * ch, a * a * sh, -b * b * c, -b * b * s])
        third = np.array([a**3 * sh, a**3 * ch, b**3 * s, -(b**3) * c])
        matrix = np.array(
            [
                [1.0, 0.0, 1.0, 0.0],  # w(0) = 0
                [0.0, a, 0.0, b],  # w'(0) = 0
                ei * curv - w2 * jt * slope,  # EI w'' = ω² J w'  (end moment drives the tip inertia)
                ei * third + w2 * mt * value + w2 * r * slope,  # shear balances the tip mass
            ]
        )
        scale = (1.0 + ch) * (1.0 + ei * b**3 + w2 * (mt + jt * b + r * b))
        return float(np.linalg.det(matrix)) / scale

    grid = omega_eb * np.geomspace(1e-3, 1.5, 600)
    values = [determinant(w) for w in grid]
    for k in range(len(grid) - 1):
        if values[k] == 0.0:
            return grid[k] / (2.0 * math.pi)
        if values[k] * values[k + 1] < 0.0:
            return brentq(determinant, grid[k], grid[k + 1], xtol=1e-12 * omega_eb) / (2.0 * math.pi)
    raise ValueError("no bending mode below 1.5 × the Euler–Bernoulli frequency")
