# =========================================================================== analytic references
def euler_clamped_load(section: LeafSection, length: float) -> float:
    """Clamped–clamped column, weak axis: π²EI/(0.5 L)² (Euler–Bernoulli)."""
    return math.pi**2 * section.youngs_modulus * section.i_tangential_axis / (0.5 * length) ** 2


def column_load(rod: Rod, shortening: float, steps: int = 8) -> float:
    """Axial force (N, compression positive) of the clamped–clamped ``rod`` shortened by ``shortening``.

    Displacement control in ``steps`` increments, each solve started from the last.
    """
    fixed = np.zeros((rod.n + 1, 6), dtype=bool)
    fixed[[0, -1]] = True
    problem = RodProblem(rod, fixed)
    q = rod.reference()
    direction = np.zeros_like(q)
    direction[-1, 2] = -1.0
    for d in np.linspace(0.0, shortening, steps + 1)[1:]:
        q[-1, 2] = rod.reference()[-1, 2] - d
        q = problem.solve(q)
    return problem.reaction(q, direction)


def cantilever_tip(rod: Rod, deflection: float, steps: int = 10) -> tuple[float, float, float]:
    """(P, Δz, tip angle) of a cantilever along z whose tip is pushed sideways by ``deflection`` (x).

    The tip's axial position and rotation are free, so the only tip load is the lateral
    reaction P: Bisshopp & Drucker's dead-load cantilever (Δz: tip shortening along z).
    """
    fixed = np.zeros((rod.n + 1, 6), dtype=bool)
    fixed[0] = True
    fixed[-1, 0] = True
    problem = RodProblem(rod, fixed)
    q = rod.reference()
    direction = np.zeros_like(q)
    direction[-1, 0] = 1.0
    for d in np.linspace(0.0, deflection, steps + 1)[1:]:
        q[-1, 0] = d
        q = problem.solve(q)
    return problem.reaction(q, direction), rod.length - float(q[-1, 2]), float(q[-1, 4])


def bisshopp_drucker(tip_angle: float) -> tuple[float, float, float]:
    """Cantilever under a transverse tip load, elliptic-integral solution (Bisshopp & Drucker 1945).

    For tip slope φ0: k² = (1 + sin φ0)/2, sin ψ1 = 1/(√2 k); √α = K(k) − F(ψ1, k), α = PL²/EI;
    tip deflection δ/L = 1 − 2[E(k) − E(ψ1, k)]/√α... returned as (α, δ/L, shortening/L).
    """
    from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

    m = 0.5 * (1.0 + math.sin(tip_angle))  # k²
    psi1 = math.asin(1.0 / math.sqrt(2.0 * m))
    root = ellipk(m) - ellipkinc(psi1, m)
    alpha = root * root
    delta = 1.0 - 2.0 * (ellipe(m) - ellipeinc(psi1, m)) / root
    shortening = 1.0 - math.sqrt(2.0 * math.sin(tip_angle)) / root
    return alpha, delta, shortening


