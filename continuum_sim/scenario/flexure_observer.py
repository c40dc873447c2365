"""The flexure segments' nonlinear moment–rotation in a run: the plant's effect, applied every physics step.

``model.flexure_model = "nonlinear"`` (docs/model.md, "Flexures beyond linear"): the MJCF
springs give the linear part; ``plant.flexure.FlexureEffect`` adds the remainder through
``data.qfrc_applied`` before every ``mj_step``. The cutter already makes the tick loop step
one ``mj_step`` at a time, so the hook costs one compiled call per step.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..model.options import model_geometry
from .config import ScenarioConfig
from .simulate import Observer, Simulation

if TYPE_CHECKING:
    from ..plant.flexure import FlexureEffect


class FlexureObserver(Observer):
    """Installs the nonlinear flexure remainder on the run's data; removes its share at the end."""

    def __init__(self, config: ScenarioConfig) -> None:
        self.config = config
        self.effect: FlexureEffect | None = None

    def start(self, sim: Simulation) -> None:
        from ..plant.flexure import flexure_effect  # numba loads only once a run is built

        cfg = self.config
        self.effect = flexure_effect(sim.model, tuple(sim.handles.arms), cfg.arm, model_geometry(cfg.arm, cfg.model),
                                     cfg.model.stiffness_scale)

    def before_physics_step(self, sim: Simulation) -> None:
        assert self.effect is not None  # set in start()
        self.effect.apply(sim.data)

    def close(self, sim: Simulation) -> None:
        if self.effect is not None:
            sim.data.qfrc_applied[self.effect.dofadr.ravel()] -= self.effect.last.ravel()
            self.effect.last[:] = 0.0


def flexure_observers(config: ScenarioConfig) -> list[Observer]:
    """``[FlexureObserver]`` when the configuration asks for the nonlinear flexures (and the arm has leaves), else ``[]``."""
    wanted = config.model.flexure_model == "nonlinear" and config.arm.backbone == "flexure"
    return [FlexureObserver(config)] if wanted else []
