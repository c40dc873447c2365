"""Static evaluations (gravity sag, tip deflection) on the single-arm model.

Each evaluation is two phases of constant inputs: settle a reference (no gravity / no
load), then settle again with gravity or the tip force on. Inputs are constant, so the
phases run in C with ``mujoco.rollout`` (no Python per step), and a batch of variants runs
in one call on several threads.

Two ways to get a variant's compiled model, with byte-identical results:

* ``build_model``: PyMJCF build + compile per variant (what a worker process does);
* ``patch_model``: variants that differ only in flexure stiffness or joint damping
  (``PATCHABLE``) share one compiled model; each gets a copy with ``jnt_stiffness`` and
  ``dof_damping`` recomputed by the builder's own formula (``section_links``), which
  skips the PyMJCF build (most of a short variant's cost). Tests check the copy equals a
  fresh build byte for byte (``mj_saveModel``).
"""

from __future__ import annotations

import copy
import dataclasses
import fnmatch
import json
from collections.abc import Hashable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout

from .. import kinematics as kin
from ..configio import to_dict
from ..control.arm import ArmController
from ..model import names
from ..model.arm import build_single_arm_model, section_links
from ..model.cable_elasticity import cable_stiffness
from ..model.options import ModelOptions, model_geometry
from ..model.state import set_arm_configuration
from ..scenario.config import ScenarioConfig
from .evaluations import Evaluation, EvaluationFailed, GravitySag, TipDeflection
from .payload import PAYLOAD_BODY, add_payload, tool_payload

FULL = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
CTRL = int(mujoco.mjtState.mjSTATE_CTRL)
XFRC = int(mujoco.mjtState.mjSTATE_XFRC_APPLIED)

# Config fields that change only jnt_stiffness / dof_damping of the single-arm model, plus
# fields the single-arm model never reads (control is applied through the inputs).
PATCHABLE = (
    "model.stiffness_scale",
    "model.joint_damping",
    "arm.material.youngs_modulus",
    "arm.material.poisson_ratio",
    "arm.sections.*.hinge_width",
    "arm.sections.*.hinge_thickness",
    "arm.sections.*.leaf_radius",
    "arm.sections.*.leaf_angles_deg",
    "arm.sections.*.leaf_free_length",
)
UNUSED_BY_MODEL = ("control", "simulation", "layout")


# --------------------------------------------------------------------------- models
def model_options(config: ScenarioConfig, evaluation: Evaluation) -> ModelOptions:
    """The variant's model options at its stable step (``model.cable_elasticity.stable_timestep``)."""
    from ..model.cable_elasticity import stable_timestep

    options = config.model
    if isinstance(evaluation, TipDeflection) and evaluation.cables == "free":
        options = dataclasses.replace(options, tendons=False)
    return dataclasses.replace(options, timestep=stable_timestep(config.arm, options))


def tool_of(evaluation: Evaluation) -> str:
    return evaluation.tool if isinstance(evaluation, (GravitySag, TipDeflection)) else "none"


def build_model(config: ScenarioConfig, evaluation: Evaluation) -> mujoco.MjModel:
    """The variant's own single-arm model carrying its tool as a payload: PyMJCF build and compile."""
    tool = tool_of(evaluation)
    root = build_single_arm_model(config.arm, model_options(config, evaluation), tool)
    add_payload(root, names.SINGLE_ARM, tool_payload(config, tool))
    return mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())


def payload_mass(model: mujoco.MjModel) -> float:
    """Mass (kg) of the tool payload the model carries (0 without one)."""
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, names.scoped(names.SINGLE_ARM, PAYLOAD_BODY))
    return float(model.body_mass[body]) if body >= 0 else 0.0


def _flat(data: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(data, dict):
        out: dict[str, Any] = {}
        for key, value in data.items():
            out.update(_flat(value, f"{prefix}.{key}" if prefix else str(key)))
        return out
    if isinstance(data, list) and data and isinstance(data[0], dict):
        out = {}
        for i, value in enumerate(data):
            out.update(_flat(value, f"{prefix}.{i}"))
        return out
    return {prefix: data}


def structure_key(config: ScenarioConfig, evaluation: Evaluation) -> str:
    """Equal keys ⇒ the compiled models differ only in the ``PATCHABLE`` arrays."""
    flat = _flat(to_dict(config))
    kept = {
        path: value
        for path, value in flat.items()
        if path.split(".")[0] not in UNUSED_BY_MODEL and not any(fnmatch.fnmatchcase(path, p) for p in PATCHABLE)
    }
    return json.dumps({"config": kept, "evaluation": evaluation.to_dict()}, sort_keys=True)


def _joint_dofs(model: mujoco.MjModel, config: ScenarioConfig, options: ModelOptions) -> list[list[tuple[int, str]]]:
    """(joint id, axis) of each section, in disk order (``arm/joint_<i>`` = "ball", or ``_x``/``_y``/``_z``)."""
    geom = model_geometry(config.arm, options)
    suffixes = {"ball": [""], "hinge_pair": ["_x", "_y"], "hinge_triple": ["_x", "_y", "_z"]}[options.joint]
    out, disk = [], 1
    for section in geom.sections:
        ids = []
        for _ in range(section.n_segments):
            for suffix in suffixes:
                name = names.scoped(names.SINGLE_ARM, names.joint(disk, suffix.lstrip("_") or None))
                jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
                if jid < 0:
                    raise KeyError(f"joint {name} not found")
                ids.append((jid, suffix.lstrip("_") or "ball"))
            disk += 1
        out.append(ids)
    return out


def patch_model(shared: mujoco.MjModel, config: ScenarioConfig, evaluation: Evaluation) -> mujoco.MjModel:
    """A copy of ``shared`` with this variant's flexure stiffness (per axis) and joint damping."""
    options = model_options(config, evaluation)
    model = copy.copy(shared)
    links = section_links(config.arm, options)
    for ids, section_links_k in zip(_joint_dofs(model, config, options), links):
        link = section_links_k[0]
        per_axis = {
            "ball": 0.5 * (link.bending_stiffness + link.stiffness_y),
            "x": link.bending_stiffness,
            "y": link.stiffness_y,
            "z": link.twist_stiffness,
        }
        for jid, axis in ids:
            model.jnt_stiffness[jid] = per_axis[axis]
            dof = model.jnt_dofadr[jid]
            ndof = 3 if model.jnt_type[jid] == mujoco.mjtJoint.mjJNT_BALL else 1
            model.dof_damping[dof : dof + ndof] = link.damping
    return model


def model_bytes(model: mujoco.MjModel) -> bytes:
    """The whole compiled model as bytes (for identity checks)."""
    buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


# ---------------------------------------------------------------------------- cases
@dataclass
class Case:
    """One variant ready to simulate: model, initial state, the two phases' inputs."""

    config: ScenarioConfig
    evaluation: Evaluation
    model: mujoco.MjModel
    initial: np.ndarray
    control_spec: int
    inputs: tuple[np.ndarray, np.ndarray]  # phase A, phase B input vectors (control_spec layout)
    gravity: tuple[np.ndarray, np.ndarray]  # phase A, phase B gravity
    nstep: int
    point_site: int  # where displacement is measured
    ctrl: np.ndarray
    target: np.ndarray | None  # PCC prediction of the measured point (gravity sag)
    force: np.ndarray | None  # tip force, world frame (tip deflection)
    tip_body: int


def _open_loop_ctrl(config: ScenarioConfig, options: ModelOptions, q: np.ndarray, tool_length: float) -> np.ndarray:
    """The package's open-loop controller: planned cable lengths minus the pre-tension offset."""
    geom = model_geometry(config.arm, options)
    control = dataclasses.replace(config.control, mode="open")
    # per-cable stiffness (elastic: EA/L; lumped: cable_kp), as the task's controller uses
    controller = ArmController(geom, control, np.eye(4), tool_length, cable_stiffness(config.arm, options))
    pose = kin.tool_centre_pose(geom, q, tool_length)
    return controller.update(q, pose, pose[:3, 3], pose[:3, :3], 0.0)


def prepare(model: mujoco.MjModel, config: ScenarioConfig, evaluation: Evaluation) -> Case:
    """Initial state (the planned pose) and constant phase inputs of one variant."""
    options = model_options(config, evaluation)
    geom = model_geometry(config.arm, options)
    q = np.radians(np.asarray(evaluation.q_deg, dtype=float))  # type: ignore[attr-defined, type-var]
    data = mujoco.MjData(model)
    set_arm_configuration(model, data, geom, names.SINGLE_ARM, q, options.joint)
    initial = np.empty(mujoco.mj_stateSize(model, FULL))
    mujoco.mj_getState(model, data, initial, FULL)

    tool = tool_of(evaluation)
    tool_length = config.arm.tools.length(tool)
    ctrl = _open_loop_ctrl(config, options, q, tool_length) if model.nu else np.zeros(0)
    g = np.array(model.opt.gravity)
    zero = np.zeros(3)
    tip_site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, names.scoped(names.SINGLE_ARM, names.TOOL_MOUNT_SITE))
    tip_body = int(model.site_bodyid[tip_site])
    if isinstance(evaluation, GravitySag):
        spec = CTRL
        data.ctrl[:] = ctrl
        vec = np.empty(mujoco.mj_stateSize(model, spec))
        mujoco.mj_getState(model, data, vec, spec)
        inputs = (vec, vec)
        gravity = (zero, g)
        point = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, names.scoped(names.SINGLE_ARM, names.TCP_SITE))
        target = kin.tool_centre_pose(geom, q, tool_length)[:3, 3]
        force = None
        settle = evaluation.settle_s
    elif isinstance(evaluation, TipDeflection):
        spec = CTRL | XFRC
        direction = np.asarray(evaluation.direction, dtype=float)
        force = evaluation.force_n * direction / np.linalg.norm(direction)
        data.ctrl[:] = ctrl
        phase_inputs = []
        for f in (zero, force):
            data.xfrc_applied[:] = 0.0
            data.xfrc_applied[tip_body, :3] = f  # at the tip disk's centre of mass = its centre
            vec = np.empty(mujoco.mj_stateSize(model, spec))
            mujoco.mj_getState(model, data, vec, spec)
            phase_inputs.append(vec)
        inputs = (phase_inputs[0], phase_inputs[1])
        gravity = (g, g) if evaluation.gravity else (zero, zero)
        point = tip_site
        target = None
        settle = evaluation.settle_s
    else:
        raise TypeError(f"not a static evaluation: {evaluation.kind}")
    nstep = max(1, int(round(settle / model.opt.timestep)))
    return Case(config, evaluation, model, initial, spec, inputs, gravity, nstep, point, ctrl, target, force, tip_body)


# ----------------------------------------------------------------------- simulation
def simulate(cases: list[Case], nthread: int = 1) -> list[dict[str, float | None] | EvaluationFailed]:
    """Run both phases of every case (same size signature and nstep) and measure them."""
    if not cases:
        return []
    if len({(c.nstep, c.control_spec) for c in cases}) != 1:
        raise ValueError("a batch must share nstep and control_spec")
    models = [c.model for c in cases]
    nthread = max(1, min(nthread, len(cases)))
    datas = [mujoco.MjData(models[0]) for _ in range(nthread)]
    nstep = cases[0].nstep
    state = np.stack([c.initial for c in cases])
    compiled_gravity = [np.array(c.model.opt.gravity) for c in cases]
    finals = []
    for phase in range(2):
        for c in cases:
            c.model.opt.gravity[:] = c.gravity[phase]
        control = np.stack([c.inputs[phase] for c in cases])[:, None, :]
        states, _ = rollout.rollout(models, datas, state, control, control_spec=cases[0].control_spec, nstep=nstep)
        state = np.ascontiguousarray(states[:, -1, :])
        finals.append(state.copy())
    for c, g in zip(cases, compiled_gravity):  # leave the models as compiled
        c.model.opt.gravity[:] = g
    results: list[dict[str, float | None] | EvaluationFailed] = []
    for i, c in enumerate(cases):
        try:
            results.append(_metrics(c, finals[0][i], finals[1][i]))
        except EvaluationFailed as exc:
            results.append(exc)
    return results


def _observe(case: Case, state: np.ndarray, phase: str, expected_time: float) -> mujoco.MjData:
    if not np.all(np.isfinite(state)):
        raise EvaluationFailed(f"diverged: non-finite state at the end of the {phase} phase")
    if abs(state[0] - expected_time) > 1e-9 * max(1.0, expected_time):
        raise EvaluationFailed(f"diverged: MuJoCo reset the unstable simulation during the {phase} phase")
    data = mujoco.MjData(case.model)
    mujoco.mj_setState(case.model, data, state, FULL)
    data.ctrl[:] = case.ctrl
    mujoco.mj_forward(case.model, data)
    return data


def _metrics(case: Case, final_a: np.ndarray, final_b: np.ndarray) -> dict[str, float | None]:
    dt = case.model.opt.timestep
    a = _observe(case, final_a, "reference", case.nstep * dt)
    p_a = a.site_xpos[case.point_site].copy()
    b = _observe(case, final_b, "loaded", 2 * case.nstep * dt)
    p_b = b.site_xpos[case.point_site].copy()
    tension = 0.0 - np.asarray(b.actuator_force)  # cable tension >= 0 (and no -0.0)
    speed = float(np.max(np.abs(b.qvel)))
    if not speed < 1e3:
        raise EvaluationFailed(f"diverged: joint speed {speed:.3g} rad/s at the end")
    mm = 1000.0
    if isinstance(case.evaluation, GravitySag):
        return {
            "sag_mm": mm * float(np.linalg.norm(p_b - p_a)),
            "sag_z_mm": mm * float(p_a[2] - p_b[2]),
            "pcc_error_mm": mm * float(np.linalg.norm(p_b - case.target)),
            "shape_error_mm": mm * float(np.linalg.norm(p_a - case.target)),
            "max_cable_tension_n": float(tension.max()),
            "min_cable_tension_n": float(tension.min()),
            "residual_speed_rad_s": speed,
            "payload_kg": payload_mass(case.model),
        }
    force = case.force
    unit = force / np.linalg.norm(force) if np.linalg.norm(force) > 0 else np.zeros(3)  # type: ignore[arg-type, operator]
    along = mm * float((p_b - p_a) @ unit)
    prediction = None
    if case.evaluation.cables == "free" and not case.evaluation.gravity and np.linalg.norm(force) > 0:  # type: ignore[arg-type, attr-defined]
        prediction = mm * float(np.linalg.norm(_linear_deflection(case, a)))
    return {
        "deflection_mm": mm * float(np.linalg.norm(p_b - p_a)),
        "deflection_along_force_mm": along,
        "compliance_mm_per_n": along / case.evaluation.force_n if case.evaluation.force_n > 0 else None,  # type: ignore[attr-defined]
        "linear_prediction_mm": prediction,
        "max_cable_tension_n": float(tension.max()) if tension.size else None,
        "residual_speed_rad_s": speed,
        "payload_kg": payload_mass(case.model),
    }


def _linear_deflection(case: Case, data: mujoco.MjData) -> np.ndarray:
    """Small-load tip displacement of the spring chain, J K⁻¹ Jᵀ F (no cables, no gravity)."""
    model = case.model
    jacp = np.zeros((3, model.nv))
    mujoco.mj_jac(model, data, jacp, None, data.xipos[case.tip_body], case.tip_body)
    k = np.array([model.jnt_stiffness[model.dof_jntid[d]] for d in range(model.nv)])
    return jacp @ ((jacp.T @ case.force) / k)


# ------------------------------------------------------------------------ entry points
def evaluate_static(config: ScenarioConfig, evaluation: Evaluation) -> dict[str, float | None]:
    """One variant on its own freshly built model (raises ``EvaluationFailed``)."""
    (result,) = simulate([prepare(build_model(config, evaluation), config, evaluation)])
    if isinstance(result, EvaluationFailed):
        raise result
    return result


def structural_paths(paths: Sequence[str]) -> list[str]:
    """The swept ``paths`` that can change ``structure_key`` (the others are patched or unused by the model).

    A config that differs from another only in its values at the other paths has the
    same key, so a sweep groups its variants by their values at these paths alone instead
    of ``structure_key``'s ~2 ms per config (10^5 variants: 190 s). A path inside a
    patchable list (``...leaf_angles_deg.1``) counts as structural: more groups, same results.
    """
    return [path for path in paths
            if path.split(".")[0] not in UNUSED_BY_MODEL and not any(fnmatch.fnmatchcase(path, p) for p in PATCHABLE)]


def evaluate_static_shared(
    configs: list[ScenarioConfig], evaluation: Evaluation, nthread: int = 1, chunk: int | None = None,
    keys: Sequence[Hashable] | None = None,
) -> Iterator[tuple[list[int], list[dict[str, float | None] | EvaluationFailed]]]:
    """Many variants, one compiled model per structure, ``nthread`` rollout threads.

    Yields (indices into ``configs``, their results) chunk by chunk, so a caller can
    record finished variants while the rest run. ``keys``: one per config, equal exactly
    where ``structure_key`` is (a sweep's values at its ``structural_paths``).
    """
    chunk = chunk or max(4, 4 * nthread)
    groups: dict[Hashable, list[int]] = {}
    for i, config in enumerate(configs):
        groups.setdefault(structure_key(config, evaluation) if keys is None else keys[i], []).append(i)
    for members in groups.values():
        try:
            shared = build_model(configs[members[0]], evaluation)
        except Exception as exc:  # noqa: BLE001 - recorded per variant, the sweep goes on
            yield members, [EvaluationFailed(_describe(exc))] * len(members)
            continue
        for start in range(0, len(members), chunk):
            part = members[start : start + chunk]
            try:
                cases = [prepare(patch_model(shared, configs[i], evaluation), configs[i], evaluation) for i in part]
                by_nstep: dict[int, list[int]] = {}
                for j, case in enumerate(cases):
                    by_nstep.setdefault(case.nstep, []).append(j)
                done = [([part[j] for j in js], simulate([cases[j] for j in js], nthread)) for js in by_nstep.values()]
            except Exception as exc:  # noqa: BLE001
                yield part, [EvaluationFailed(_describe(exc))] * len(part)
                continue
            yield from done


def _describe(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


__all__ = [
    "EvaluationFailed",
    "PATCHABLE",
    "build_model",
    "evaluate_static",
    "evaluate_static_shared",
    "model_bytes",
    "patch_model",
    "structural_paths",
    "structure_key",
]
