"""Toolpaths and the timed plan of the sample-removal task (SPEC §5; paper §4.2, §5.2).

Stages (``STAGE_NAMES``): 1 initial, 2 clamping (the gripper approaches the sample's side
edge and closes), 3 milling (the grinder's approach → cutting → exit → return, spindle on,
vertical = plate normal, slow feed on the cut), 4 retrieval (the gripper carries the sample
away), 5 return (the grinder goes back to its initial configuration). One arm moves at a
time; the other holds its configuration.

Free-space transfers from and to the initial configuration are joint-space moves
(linear in bending coordinates, so the straight arm's undefined phase is harmless);
every move near the plate is a Cartesian toolpath, discretised every
``waypoint_spacing``, solved by warm-started IK under per-step (Δθ, Δφ) limits
(``ik.solve_path``) and interpolated between solved points by paper eq. 12. Timing:
trapezoidal speed profiles along the path (feed speed per segment). The plan is refused
(``UnreachableError``, a ``ConfigError``) if a pose is outside an arm's workspace or a
path cannot be followed, naming the first offending point.

Modules, lowest first: ``config`` (``PlanConfig``), ``task_plan`` (``TaskPlan``, stage names,
the .npz file), ``timing`` (trapezoidal profiles), ``poses`` (key poses, densified
toolpaths), ``clearance`` (collision envelopes), ``moves`` (dwells, joint transfers,
IK-solved paths), ``plan_metrics``, ``sampling`` (moves → samples), ``planner``
(``plan_task``), ``planar_demo`` (paper Fig. 10/11).
"""

from .clearance import arm_clearance, arm_envelope, plate_clearance, sample_box_gaps
from .config import PlanConfig
from .planar_demo import planar_demo_path, solve_planar_demo
from .planner import plan_task
from .poses import densify, grinder_poses, gripper_poses
from .sampling import MAX_PLAN_SAMPLES, check_plan_samples
from .task_plan import SEGMENT_NAMES, STAGE_NAMES, TaskPlan, save_plan
from .timing import trapezoid_duration, trapezoid_position

__all__ = [
    "MAX_PLAN_SAMPLES",
    "SEGMENT_NAMES",
    "STAGE_NAMES",
    "PlanConfig",
    "TaskPlan",
    "arm_clearance",
    "arm_envelope",
    "check_plan_samples",
    "densify",
    "grinder_poses",
    "gripper_poses",
    "planar_demo_path",
    "plan_task",
    "plate_clearance",
    "sample_box_gaps",
    "save_plan",
    "solve_planar_demo",
    "trapezoid_duration",
    "trapezoid_position",
]
