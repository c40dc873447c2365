"""A controller of your own: the paper's open loop with a slower gripper.

Run it (from the repository root, so ``examples`` is importable):

    continuum-sim run --controller examples.hold_controller:SlowGripOpenLoop --out runs/custom

A controller is any class with ``reset(context)`` and ``command(state) -> MotorCommands``
(``continuum_sim.controllers``). This one reuses the built-in open-loop arm controller for the
cables and adds its own gripper ramp: it closes the jaws at half the motor's speed limit.
"""

from __future__ import annotations

from continuum_sim.controllers import ControlContext, MeasuredState, MotorCommands, PlanTrackingController


class SlowGripOpenLoop:
    """Open-loop cables; gripper cable ramped at half speed toward the plan's open/closed command."""

    def reset(self, context: ControlContext) -> None:
        self.arms = PlanTrackingController("open")
        self.arms.reset(context)
        self.plan = context.plan
        self.tools = context.config.scene.tools
        self.gripper = self.tools.gripper_cable_open

    def command(self, state: MeasuredState) -> MotorCommands:
        commands = self.arms.command(state)  # cable set-points of the planned shapes (and the plan's spindle)
        closed = bool(self.plan.gripper_closed[state.plan_index])
        target = self.tools.gripper_cable_closed if closed else self.tools.gripper_cable_open
        reach = 0.5 * self.tools.gripper_cable_speed * state.dt
        self.gripper += min(max(target - self.gripper, -reach), reach)
        commands.gripper_cable = self.gripper
        return commands
