"""A new physics effect, worked through (docs/architecture.md, "Adding a physics effect"):
viscous drag on every joint of the arms' disks, tau = -b * qdot.

Run it on the task (from the repository root, so ``examples`` is importable):

    python -c "from continuum_sim.scenario.config import ScenarioConfig; \
from continuum_sim.scenario.runner import run_scenario; from examples.joint_drag import JointDrag; \
print(run_scenario(ScenarioConfig.default(), None, stages=('initial', 'clamping'), observers=[JointDrag(1e-3)])['tip_error_mm'])"

Its state (the dofs it acts on, the force it added last) lives in the instance, one per MjData:
nothing module-level, so two simulations in one process never share it. The oracle it is tested
against is MuJoCo itself: the same coefficient as ``dof_damping`` gives ``qfrc_damper``
(tests/test_joint_drag_example.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from continuum_sim.scenario.simulate import Observer, Simulation


def disk_dofs(model: Any, bodies: np.ndarray) -> np.ndarray:
    """Every dof of the given bodies' joints, in model order."""
    return np.concatenate([np.arange(model.body_dofadr[b], model.body_dofadr[b] + model.body_dofnum[b]) for b in bodies])


class JointDrag(Observer):
    """Viscous drag ``-coefficient * qvel`` (N m s/rad, *assumed*) on the disks' joints, applied before every mj_step."""

    def __init__(self, coefficient: float, dofs: np.ndarray | None = None) -> None:
        if not (np.isfinite(coefficient) and coefficient >= 0.0):
            raise ValueError(f"coefficient: must be finite and >= 0 (got {coefficient!r})")
        self.coefficient = float(coefficient)
        self.dofs = dofs
        self.added = np.zeros(0)

    def start(self, sim: Simulation) -> None:
        if self.dofs is None:  # both arms' disks, from the scene's handles
            self.dofs = np.concatenate([disk_dofs(sim.model, sim.handles.disk_bodies[arm]) for arm in sim.handles.arms])
        self.added = np.zeros(len(self.dofs))

    def before_physics_step(self, sim: Simulation) -> None:
        # qfrc_applied is shared with other effects and MuJoCo never clears it: replace our own share only.
        force = -self.coefficient * sim.data.qvel[self.dofs]
        sim.data.qfrc_applied[self.dofs] += force - self.added
        self.added = force
