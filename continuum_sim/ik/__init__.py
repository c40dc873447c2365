"""Optimisation inverse kinematics (SPEC §3; paper eq. 8-12).

One concept per module, lowest first:

- ``options``: the modes (orientation 'full'/'axis', phase 'free'/'planar') and ``IKOptions``.
- ``targets``: what the solver is given, checked (poses, configurations, tools, the arm frame).
- ``problem``: ``IKProblem``, the solver variables (bending coordinates) and the weighted
  residual of paper eq. 8-11 with its analytic Jacobian.
- ``solver``: ``IKSolver``, projected Levenberg-Marquardt, the warm-start chord step and the
  cold-start seed table.
- ``pose``: ``solve_ik`` (one pose) and the per-arm solver cache.
- ``path``: ``solve_path`` (a toolpath, warm-started under per-step limits) and paper eq. 12.
"""

from .options import ORIENTATIONS, PHASES, IKOptions, Orientation, Phase
from .path import PathSolution, StepLimits, interpolate_pose, interpolate_q, solve_path, step_violations, unwrap_phases
from .pose import IKResult, get_solver, solve_ik
from .problem import Evaluation, IKProblem
from .solver import ChordIterate, IKSolver, Iterate, Solution
from .targets import to_arm_frame, tool_length_of, validate_pose, validate_q

__all__ = [
    "ORIENTATIONS",
    "PHASES",
    "ChordIterate",
    "Evaluation",
    "IKOptions",
    "IKProblem",
    "IKResult",
    "IKSolver",
    "Iterate",
    "Orientation",
    "PathSolution",
    "Phase",
    "Solution",
    "StepLimits",
    "get_solver",
    "interpolate_pose",
    "interpolate_q",
    "solve_ik",
    "solve_path",
    "step_violations",
    "to_arm_frame",
    "tool_length_of",
    "unwrap_phases",
    "validate_pose",
    "validate_q",
]
