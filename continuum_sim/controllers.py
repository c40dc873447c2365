"""The controller protocol: what drives the robot's motors once per control tick.

A controller is any object with

* ``reset(context: ControlContext) -> None``: called once before the run, with the plan,
  the geometry, the layout, the configuration and the control period;
* ``command(state: MeasuredState) -> MotorCommands``: called once per control tick with
  what the robot's sensors measure (tool poses, cable tensions and lengths, whether the
  sample is free) and returns the motor set-points (each arm's cable lengths, the gripper
  cable, the spindle speed).

The runner applies the commands to the actuators (``scenario.simulate.apply_commands``)
and steps the physics until the next tick. The built-in ``open`` (the paper's method) and
``closed`` (ours) controllers are two implementations (``PlanTrackingController``); a
user's own class is named in the configuration (``control.controller = "module:Class"``)
or on the command line (``--controller module:Class``), see ``load_controller``.
"""

from __future__ import annotations

import dataclasses
import importlib
import os
import sys
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from .configio import ConfigError
from .geometry import ArmGeometry
from .layout import TaskLayout

if TYPE_CHECKING:
    from .scenario.config import ScenarioConfig
    from .toolpath import TaskPlan

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ControlContext:
    """What a controller may know before the run starts (fixed for the run)."""

    plan: TaskPlan  # the timed plan both arms follow (plan.q(arm), plan.tcp(arm), gripper/spindle flags)
    geometry: ArmGeometry  # the simulated model's geometry (segment count as simulated)
    layout: TaskLayout  # arm mounts (base frames), tools, plate
    config: ScenarioConfig  # the whole run configuration (control gains, cable kp, tool options)
    arms: tuple[str, ...]  # arm names, in the order of every per-arm array
    tool_arm: dict[str, str]  # tool name -> the arm carrying it ("grinder", "gripper")
    control_period: float  # s between two ``command`` calls


@dataclass(frozen=True)
class ArmMeasurement:
    """One arm as its sensors see it at a control tick (world frame, SI units)."""

    tcp_pos: Array  # (3,) tool-centre point position (m)
    tcp_mat: Array  # (3, 3) tool frame (columns x, y, z)
    cable_tension: Array  # (3·sections,) N, ≥ 0, from the motors' force readings
    cable_length: Array  # (3·sections,) m, measured cable path lengths


@dataclass(frozen=True)
class MeasuredState:
    """The measured state a controller reads each tick."""

    time: float  # s, simulated
    dt: float  # s since the previous ``command`` call (0 for the priming call before the first step)
    plan_index: int  # sample of ``context.plan`` the run is at
    arms: dict[str, ArmMeasurement]
    sample_detached: bool  # the sample is cut free of the plate


@dataclass
class MotorCommands:
    """Motor set-points for one control tick.

    ``cable_lengths[arm]``: commanded length of each cable (m, the tendon position
    actuators' control; shorter than the cable's path = tension). ``gripper_cable``:
    the gripper's closing cable command (m, 0 = open, see ``ToolOptions``). ``spindle_speed``:
    rad/s. ``bending`` / ``common_mode``: optional per-arm diagnostics a controller may fill
    (commanded bending coordinates (u, v) per section; common-mode shortening per section,
    m), recorded in the trajectory (NaN when left empty).
    """

    cable_lengths: dict[str, Array]
    gripper_cable: float
    spindle_speed: float
    bending: dict[str, Any] = field(default_factory=dict)
    common_mode: dict[str, Array] = field(default_factory=dict)


@runtime_checkable
class Controller(Protocol):
    """Anything with ``reset(context)`` and ``command(state) -> MotorCommands``."""

    def reset(self, context: ControlContext) -> None: ...

    def command(self, state: MeasuredState) -> MotorCommands: ...


class ToolSequencer:
    """The tools' motor commands from the plan: spindle on/off, gripper cable ramped.

    The gripper motor runs its cable toward open/closed at its speed limit
    (``tools.gripper_cable_speed``): a step command slammed the jaws onto the plate (12 N
    contact transient on a 2 N grip). Usable by any controller that follows the plan's
    tool schedule.
    """

    def __init__(self, context: ControlContext) -> None:
        self.plan = context.plan
        self.tools = context.config.scene.tools
        self.gripper_cable = self.tools.gripper_cable_open  # the motor starts where MjData's ctrl does (0)

    def command(self, state: MeasuredState) -> tuple[float, float]:
        """(gripper cable, spindle speed) for this tick."""
        i = state.plan_index
        tools = self.tools
        target = tools.gripper_cable_closed if self.plan.gripper_closed[i] else tools.gripper_cable_open
        reach = tools.gripper_cable_speed * state.dt
        self.gripper_cable = self.gripper_cable + min(max(target - self.gripper_cable, -reach), reach)
        return self.gripper_cable, tools.spindle_speed if self.plan.spindle_on[i] else 0.0


def plan_at(plan: TaskPlan, arm: str, t: float) -> tuple[Array, Array]:
    """(q, tcp) of ``arm``'s plan at time ``t``, linearly interpolated between samples.

    The plan is sampled at 100 Hz and the control tick runs at 125 Hz: taking the nearest
    sample repeated every fifth one, which modulated the set-point rate at the 25 Hz beat
    and rang the cables (docs/plant.md, "Tension chatter").
    """
    from .control.kernels import plan_sample  # numba: loaded with the controllers, not with the config

    as_samples = np.ascontiguousarray  # float64, C order: one compiled signature (no copy for the plan's own arrays)
    return plan_sample(as_samples(plan.t, np.float64), float(t), as_samples(plan.q(arm), np.float64),
                       as_samples(plan.tcp(arm), np.float64))


class PlanTrackingController:
    """The built-in controllers: each arm follows the plan through ``control.ArmController``.

    ``mode`` ``"open"`` (the paper's method: cable lengths of the planned shape) or
    ``"closed"`` (ours: the planned shape corrected by the measured tool-pose error);
    None takes ``config.control.mode``. The gripper arm holds its command while its jaws
    are shut on the still-welded sample (``ArmController.update``'s ``holding``).
    """

    def __init__(self, mode: Literal["open", "closed"] | None = None) -> None:
        self.mode = mode
        self._arms: dict[str, Any] = {}

    def reset(self, context: ControlContext) -> None:
        from .control.arm import ArmController
        from .model.cable_elasticity import cable_stiffness

        cfg = context.config
        control = cfg.control if self.mode is None else dataclasses.replace(cfg.control, mode=self.mode)
        self.plan = context.plan
        self.gripper_arm = context.tool_arm["gripper"]
        self.grinder_arm = context.tool_arm["grinder"]
        self.plant_gains: dict[str, Any] = {}  # arm -> gains.PlantGain (gain_mode "plant")
        if control.gain_mode == "plant" and control.mode == "closed":
            from .gains import plant_gain

            for arm in context.arms:
                tool = context.layout.tool_of(arm)
                self.plant_gains[arm] = plant_gain(
                    context.geometry,
                    cfg.model,
                    control.outer_gain,
                    control.mode_fraction,
                    control.pretension,
                    cable_stiffness(cfg.arm, cfg.model),
                    tool_mass={"grinder": cfg.model.grinder_mass, "gripper": cfg.model.gripper_mass}.get(tool, 0.0),
                    tool_length=cfg.arm.tools.length(tool),
                )
        self._arms = {
            arm: ArmController(
                context.geometry,
                control,
                context.layout.mount(arm).base_transform(),
                cfg.arm.tools.length(context.layout.tool_of(arm)),
                cable_stiffness(cfg.arm, cfg.model),  # per cable: EA/L (elastic) or the lumped gain
                roll_free=arm == self.grinder_arm,  # the cutter is axisymmetric (planned in 'axis' mode too)
                gain=self.plant_gains[arm].matrix if arm in self.plant_gains else None,
            )
            for arm in context.arms
        }
        self.tools = ToolSequencer(context)

    def planned(self, arm: str, state: MeasuredState) -> tuple[Array, Array]:
        """(q, tool-centre pose) ``arm`` is asked to follow at this tick: the plan at the tick's time.

        The extension point for shifting the reference (``env.CorrectedController`` adds an
        agent's bending-coordinate correction here).
        """
        return plan_at(self.plan, arm, state.time)  # interpolated at the tick's time (see plan_at)

    def command(self, state: MeasuredState) -> MotorCommands:
        i = state.plan_index
        # The gripper holds something fixed while its jaws are shut on the still-welded sample.
        holding = bool(self.plan.gripper_closed[i]) and not state.sample_detached
        lengths, bending, common = {}, {}, {}
        for arm, controller in self._arms.items():
            m = state.arms[arm]
            q_plan, tcp_plan = self.planned(arm, state)
            lengths[arm] = controller.update(
                q_plan, tcp_plan, m.tcp_pos, m.tcp_mat, state.dt,
                holding and arm == self.gripper_arm, m.cable_tension,
            )
            bending[arm] = controller.last_command
            common[arm] = controller.extra
        gripper, spindle = self.tools.command(state)
        return MotorCommands(lengths, gripper, spindle, bending, common)


class OpenLoopController(PlanTrackingController):
    """The paper's open loop: cable lengths of the planned shape, pre-tensioned."""

    def __init__(self) -> None:
        super().__init__("open")


class ClosedLoopController(PlanTrackingController):
    """Ours: the planned shape plus an integrated tool-pose correction, with tension keeping."""

    def __init__(self) -> None:
        super().__init__("closed")


BUILTIN = {"open": OpenLoopController, "closed": ClosedLoopController}


class ControllerError(ConfigError):
    """A controller spec that does not import or does not satisfy the protocol (one-line message)."""

    def __init__(self, message: str) -> None:
        super().__init__("control.controller", message)


def controller_spec(config: ScenarioConfig) -> str:
    """The controller a configuration asks for: ``control.controller`` if set, else ``control.mode``."""
    return config.control.controller or config.control.mode


def load_controller(spec: str) -> Controller:
    """A controller instance from ``"open"``, ``"closed"`` or ``"package.module:ClassName"``.

    The module is imported with the current directory on ``sys.path`` (so a file of your own
    next to where you run works: ``my_controller:MyController``); the class is called with no
    arguments and must have ``reset(context)`` and ``command(state)``. Raises
    ``ControllerError`` (a ``ConfigError``: the CLI exits 2) with one line naming what is wrong.
    """
    if spec in BUILTIN:
        return BUILTIN[spec]()
    module_name, sep, class_name = spec.partition(":")
    if not sep or not module_name or not class_name:
        raise ControllerError(f"expected 'open', 'closed' or 'module:Class' (got {spec[:80]!r})")
    cwd = os.getcwd()
    added = cwd not in sys.path
    if added:
        sys.path.insert(0, cwd)
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # noqa: BLE001 - any failure inside the user's module is reported in one line
        raise ControllerError(f"cannot import {module_name!r} ({_one_line(exc)})") from None
    finally:
        if added:
            sys.path.remove(cwd)
    cls = getattr(module, class_name, None)
    if cls is None:
        raise ControllerError(f"module {module_name!r} has no {class_name!r}")
    try:
        instance = cls()
    except Exception as exc:  # noqa: BLE001
        raise ControllerError(f"{spec} cannot be created with no arguments ({_one_line(exc)})") from None
    missing = [m for m in ("reset", "command") if not callable(getattr(instance, m, None))]
    if missing:
        raise ControllerError(f"{spec} does not satisfy the Controller protocol (no {' and no '.join(missing)} method)")
    return instance


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:120]}" if text else type(exc).__name__
