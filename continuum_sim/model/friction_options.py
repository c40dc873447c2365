"""The cable-friction settings of a model (the physics: ``continuum_sim.plant.friction``)."""

from __future__ import annotations

from dataclasses import dataclass

from ..configio import ConfigError, require_range

# *Assumed* default μ: a steel rope sliding in the holes of 3D-printed polymer disks (the
# prototype's disks are printed, Table 1 of the paper). Dry steel on nylon/PLA/PTFE lies
# at μ ≈ 0.05–0.25 in engineering friction tables; 0.15 is the middle of the 0.1–0.2 range
# the issue names for steel rope in polymer or PTFE-lined holes. Not measured on the robot.
DEFAULT_MU = 0.15
# Stick band: 1 mm of sliding builds friction from zero to full after a reversal. A
# numerical regularisation of ideal stick (a steel rope's own stretch over one 15–21 mm
# piece at a ~1 N friction step is ~1 µm). The presliding stiffness μβT/δ enters the
# explicit passive force, so δ must keep it inside the 4 ms step's stability limit: with
# the gripper holding the welded sample (the jaws reaching the grasp since the preloaded
# jaw springs) δ = 0.2 mm rang the gripper arm's cables at 18 Hz, 9 N peak-to-peak above
# 10 Hz and 6 solver iterations per step; δ = 1 mm: 0.00 N and 1 iteration, as at 2 ms
# (`python scripts/tension_chatter.py hold --variants default,presliding0.2mm,dt2ms`).
# The capstan does not depend on δ (< 0.1 % from 0.05 to 0.2 mm, rows `continuum-sim
# validate --only capstan`); 1 mm is 4 % of a section's 24 mm cable stroke.
DEFAULT_PRESLIDING = 1.0e-3


@dataclass(frozen=True)
class CableFrictionConfig:
    """Friction of the cables in the disk holes (μ = 0: frictionless, nothing installed)."""

    mu: float = DEFAULT_MU  # Coulomb coefficient, steel rope in printed-polymer holes (*assumed*, 0.05–0.25)
    presliding: float = DEFAULT_PRESLIDING  # m, Dahl stick band (numerical regularisation of stick)
    base_hole: bool = True  # friction also where the cable enters the base plate (arriving along the base z)

    def __post_init__(self) -> None:
        require_range("mu", self.mu, 0.0, 1.0, low_inclusive=True)
        require_range("presliding", self.presliding, 1e-7, 1e-2, low_inclusive=True)
        if not isinstance(self.base_hole, bool):
            raise ConfigError("base_hole", f"must be true or false (got {self.base_hole!r})")
