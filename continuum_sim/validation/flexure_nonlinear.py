"""Checks of the nonlinear flexure model (``plant.leaf_rod``) and its comparison with the linear one.

Textbook limits, none taken from ``model.stiffness``: the Euler load π²EI/(0.5L)² of a
clamped–clamped column (and its shear correction, Engesser: P/(1 + P/κGA)); the
large-deflection cantilever under a tip load (Bisshopp & Drucker 1945, elliptic
integrals); the small-rotation slope of a leaf, pure bending EI/g plus the stretch EA/g
times the lever arm² (hand statics). Then the segment moment against the linear
stiffness over 0–10° per segment (docs/model.md, "Flexures beyond linear";
``scripts/flexure_comparison.py`` writes the table and plot).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..plant.leaf_rod import FlexureSegment, LeafSection, Rod, RodProblem, section_segment

if TYPE_CHECKING:
    from ..geometry import ArmGeometry

# Section bends the default task commands, per section (deg), docs/model.md and
# /work/shared/reference/fidelity-notes.md: the per-segment rotation is bend / n_segments.
TASK_BEND_DEG = ((43.0, 46.0), (66.0, 86.0), (59.0, 69.0))
# The bending direction (deg, disk frame) that compresses the leaf at 0° (the first to buckle) and its opposite.
WORST_PHI_DEG, OPPOSITE_PHI_DEG = 90.0, 270.0
DIFFERENCE_RULE = 0.10  # the plant uses the nonlinear curve where it differs from linear by more than this


# =========================================================================== analytic references
def euler_clamped_load(section: LeafSection, length: float) -> float:
    """Clamped–clamped column, weak axis: π²EI/(0.5 L)² (Euler–Bernoulli)."""
    return math.pi**2 * section.youngs_modulus * section.i_tangential_axis / (0.5 * length) ** 2


def engesser_load(section: LeafSection, length: float) -> float:
    """The Euler load with shear deformation (Engesser): P_E/(1 + P_E/(κGA))."""
    p = euler_clamped_load(section, length)
    return p / (1.0 + p / (section.shear_coefficient * section.shear_modulus * section.area))


def column_load(rod: Rod, shortening: float, steps: int = 4) -> float:
    """Axial force (N, compression positive) of the clamped–clamped ``rod`` shortened by ``shortening``."""
    fixed = np.zeros((rod.n + 1, 6), dtype=bool)
    fixed[[0, -1]] = True
    problem = RodProblem(rod, fixed)
    q = rod.reference()
    z_top = float(q[-1, 2])
    direction = np.zeros_like(q)
    direction[-1, 2] = -1.0
    for d in np.linspace(0.0, shortening, steps + 1)[1:]:
        scaled = rod.reference()  # predictor: uniform compression of the previous state
        scaled[:, 2] = q[:, 2] * (z_top - d) / float(q[-1, 2])
        scaled[:, [0, 1, 3, 4, 5]] = q[:, [0, 1, 3, 4, 5]]
        q = problem.solve(scaled)
    return problem.reaction(q, direction)


def cantilever_tip(rod: Rod, deflection: float, steps: int = 4) -> tuple[float, float, float]:
    """(P, shortening along z, tip slope) of a cantilever along z whose tip is pushed by ``deflection`` in x.

    The tip's axial position and rotation are free, so the only tip load is the lateral
    reaction P: Bisshopp & Drucker's dead-load cantilever.
    """
    fixed = np.zeros((rod.n + 1, 6), dtype=bool)
    fixed[0] = True
    fixed[-1, 0] = True
    problem = RodProblem(rod, fixed)
    q = rod.reference()
    z = q[:, 2] / rod.length
    direction = np.zeros_like(q)
    direction[-1, 0] = 1.0
    for d in np.linspace(0.0, deflection, steps + 1)[1:]:
        guess = q.copy()  # predictor: the linear cantilever shape scaled to the new tip
        guess[:, 0] = q[:, 0] + (d - q[-1, 0]) * 0.5 * z * z * (3.0 - z)
        guess[:, 4] = q[:, 4] + (d - q[-1, 0]) * 1.5 * z * (2.0 - z) / rod.length
        q = problem.solve(guess)
    return problem.reaction(q, direction), rod.length - float(q[-1, 2]), float(q[-1, 4])


def bisshopp_drucker(tip_slope: float) -> tuple[float, float, float]:
    """(α = PL²/EI, tip deflection/L, tip shortening/L) of the tip-loaded cantilever whose tip slope is φ₀.

    Elliptic-integral solution (Bisshopp & Drucker 1945): k² = (1 + sin φ₀)/2,
    sin ψ₁ = 1/(√2 k), √α = K(k) − F(ψ₁, k), δ/L = 1 − 2[E(k) − E(ψ₁, k)]/√α,
    x_tip/L = √(2 sin φ₀)/√α.
    """
    from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

    m = 0.5 * (1.0 + math.sin(tip_slope))
    psi1 = math.asin(1.0 / math.sqrt(2.0 * m))
    root = float(ellipk(m) - ellipkinc(psi1, m))
    delta = 1.0 - 2.0 * float(ellipe(m) - ellipeinc(psi1, m)) / root
    return root * root, delta, 1.0 - math.sqrt(2.0 * math.sin(tip_slope)) / root


def leaf_hand_slope(segment: FlexureSegment, psi: float) -> float:
    """Small-rotation stiffness (N·m/rad) of one leaf turned about the in-plane axis at ψ (hand statics).

    The disk turns about the joint at mid-gap: the leaf's end slides g/2·θ and turns θ (a
    constant-curvature arc, pure bending, M = EI_n θ/g about the turning axis), and lifts
    by r·θ·sin ψ (a bar, F = EA·δ/g, lever r·sin ψ).
    """
    leaf, g, r = segment.leaf, segment.free_length, segment.leaf_radius
    e = leaf.youngs_modulus
    bend = e / g * (leaf.i_radial_axis * math.cos(psi) ** 2 + leaf.i_tangential_axis * math.sin(psi) ** 2)
    return bend + e * leaf.area / g * (r * math.sin(psi)) ** 2


# =========================================================================== comparison
def comparison(geometry: ArmGeometry, degrees: np.ndarray, elements: int = 24) -> list[dict[str, Any]]:
    """Per section: the segment moment about the bending axis, linear (K·θ) and nonlinear, for the two directions."""
    from ..model.stiffness import segment_stiffness

    theta = np.radians(np.asarray(degrees, dtype=float))
    out = []
    for k, sec in enumerate(geometry.sections):
        segment = section_segment(geometry, sec, elements)
        kx = segment_stiffness(geometry, sec)[0]
        entry: dict[str, Any] = {"section": k, "degrees": np.asarray(degrees, dtype=float), "linear": kx * theta}
        for name, phi_deg in (("worst", WORST_PHI_DEG), ("opposite", OPPOSITE_PHI_DEG)):
            phi = math.radians(phi_deg)
            m = segment.moment_curve(theta, phi)
            entry[name] = m @ np.array([math.cos(phi), math.sin(phi)])
        entry["task_deg"] = tuple(b / sec.n_segments for b in TASK_BEND_DEG[k]) if k < len(TASK_BEND_DEG) else None
        out.append(entry)
    return out


def onset_deg(entry: dict[str, Any], which: str = "worst") -> float:
    """The per-segment rotation (deg) past which the nonlinear moment differs from linear by > 10 % (interpolated)."""
    deg = entry["degrees"][1:]
    diff = np.abs(entry[which][1:] / entry["linear"][1:] - 1.0)
    above = np.nonzero(diff > DIFFERENCE_RULE)[0]
    if not len(above):
        return math.inf
    i = int(above[0])
    if i == 0:
        return float(deg[0])
    return float(np.interp(DIFFERENCE_RULE, [diff[i - 1], diff[i]], [deg[i - 1], deg[i]]))


def markdown_table(entries: list[dict[str, Any]], every: int = 2) -> str:
    """The comparison as a markdown table (M in N·m; ratio = nonlinear/linear)."""
    names = ("proximal", "middle", "distal")
    lines = ["| section | θ per segment (°) | linear M (N·m) | nonlinear, worst dir. (N·m) | ratio | nonlinear, opposite (N·m) | ratio |",
             "|---|---|---|---|---|---|---|"]
    for e in entries:
        for i in range(every, len(e["degrees"]), every):
            lin = e["linear"][i]
            lines.append(f"| {names[e['section']] if e['section'] < 3 else e['section']} | {e['degrees'][i]:.0f} | {lin:.3f} "
                         f"| {e['worst'][i]:.3f} | {e['worst'][i] / lin:.3f} | {e['opposite'][i]:.3f} | {e['opposite'][i] / lin:.3f} |")
    return "\n".join(lines) + "\n"


# =========================================================================== report
def validation_checks() -> list[Any]:
    """``flexure.nonlinear`` rows of ``continuum-sim validate``: the solver's limits, then the plant's curve vs the solver."""
    from .report import Check, row

    def limits(quick: bool) -> list[Any]:
        rows = []
        leaf = LeafSection(0.006, 0.001, 2.0e9, 0.38)
        ref = "clamped–clamped column, weak axis"
        if not quick:  # (the quick run keeps the cantilever; tests/test_flexure_nonlinear.py checks the column)
            slender = Rod(LeafSection(0.006, 0.0002, 2.0e9, 0.38), 0.05, 24, bow=5e-7)
            pe = euler_clamped_load(slender.section, slender.length)
            p = column_load(slender, 1.5 * pe / (slender.section.youngs_modulus * slender.section.area) * slender.length)
            rows.append(row("flexure.limits", ref + " (L/t 250, 24 elements): Euler π²EI/(0.5L)²",
                            "plateau load at 1.5× critical strain vs Euler", 100 * (p / pe - 1), 2.0, "%", "+.2f"))
            for n, tol in ((24, 2.0), (16, 3.0)):
                rod = Rod(leaf, 0.018, n, bow=9e-6)
                pe = engesser_load(leaf, 0.018)
                p = column_load(rod, 1.5 * pe / (leaf.youngs_modulus * leaf.area) * 0.018)
                rows.append(row("flexure.limits", ref + f" (proximal leaf, L/t 18, {n} elements): Engesser P_E/(1+P_E/κGA)",
                                "plateau load at 1.5× critical strain vs Engesser", 100 * (p / pe - 1), tol, "%", "+.2f"))
        rod = Rod(LeafSection(0.006, 0.0005, 2.0e9, 0.38), 0.05, 16)
        slope = 0.4614  # tip slope of α = PL²/EI ≈ 1 (Bisshopp–Drucker's table: δ/L = 0.3017)
        alpha, delta, _ = bisshopp_drucker(slope)
        p, _, tip = cantilever_tip(rod, delta * rod.length)
        measured = p * rod.length**2 / (rod.section.youngs_modulus * rod.section.i_tangential_axis)
        rows.append(row("flexure.limits", "cantilever, tip load, large deflection (Bisshopp & Drucker 1945)",
                        f"load parameter PL²/EI at δ/L = {delta:.4f} vs {alpha:.4f}", 100 * (measured / alpha - 1), 1.0, "%", "+.2f"))
        return rows

    def plant_curve(quick: bool) -> list[Any]:
        from ..plant.flexure import section_curve
        from .report import _arm_and_options

        arm, options = _arm_and_options()
        rows = []
        for k, sec in enumerate(arm.sections[:1] if quick else arm.sections):
            segment = section_segment(arm, sec, 16)
            for psi in (0.0, math.pi / 2):
                th = np.radians([0.01])
                m = segment.leaf_curve(th, psi)[0] @ np.array([math.cos(psi), math.sin(psi)])
                rows.append(row("flexure.nonlinear", f"leaf, section {k}: pure bending EI/g + stretch EA r²/g (hand)",
                                f"small-rotation slope, axis ψ {math.degrees(psi):.0f}°", 100 * (m / th[0] / leaf_hand_slope(segment, psi) - 1),
                                1.0, "%", "+.3f"))
            curve = section_curve(arm, sec)
            phi = math.radians(WORST_PHI_DEG)
            axis = np.array([math.cos(phi), math.sin(phi)])
            degrees = np.arange(0.0, 7.0, 2.0) if quick else np.arange(0.0, 11.0, 1.0)  # a continuation from 0
            exact_curve = section_segment(arm, sec, 24).moment_curve(np.radians(degrees), phi) @ axis
            for deg in ((6.0,) if quick else (2.0, 4.0, 6.0, 8.0, 10.0)):
                exact = float(np.interp(deg, degrees, exact_curve))
                plant = float(curve.moment(math.radians(deg) * axis) @ axis) if options.flexure_model == "nonlinear" \
                    else curve.linear[0] * math.radians(deg)
                linear = curve.linear[0] * math.radians(deg)
                rows.append(row("flexure.nonlinear", f"geometrically exact segment (leaf rods), section {k}",
                                f"plant moment ({options.flexure_model}) at {deg:g}°/segment, worst direction "
                                f"(linear: {100 * (linear / exact - 1):+.1f} %)", 100 * (plant / exact - 1), 3.0, "%", "+.2f"))
        return rows

    reference = "geometrically nonlinear flexure segment"
    return [Check("flexure.limits", reference + ": the rod solver vs textbook limits", limits),
            Check("flexure.nonlinear", reference + ": plant curve vs the solver", plant_curve)]
