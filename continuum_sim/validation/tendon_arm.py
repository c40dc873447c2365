"""The cable-driven arm (MuJoCo) against the Cosserat tendon model (``cosserat.py``) at known tensions.

MuJoCo side: the arm exactly as ``model.arm.build_single_arm_model`` builds it (disks,
flexure joints, cable sites and spatial tendons), one section alone or the whole arm.
Known tensions are applied as tendon forces, −τ·J_tendonᵀ, inside the static solver,
not through the cable actuators: those belong to the transmission (motor loops, elastic
ropes) and change with it, while the question here is the structure's answer to a
given tension. Tendon springs are zeroed for the same reason; at rest their damping
does nothing.

Cosserat side (independent): a Kirchhoff rod per section with EI and GJ read from
``model.stiffness`` at run time (K_seg·pitch per axis), tendons at the geometry's hole
offsets terminating at their section's last disk, the disks' weight as point masses at
the model's disk positions (mass from the geometry: density × disk volume, as designed).

Sweep (docs/validation.md): single-cable tensions 0…T_max with T_max = min(150 N, the
tension that bends the section to its 90° limit on the constant-curvature estimate
τ·r·L/EI), so that no case wraps the section into itself; two-cable pairs; gravity off,
along −z (the arm upright, SPEC frame) and along −x (sideways, the largest effect).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..geometry import ArmGeometry
from ..model import names as model_names
from ..model.options import ModelOptions, model_geometry
from ..model.stiffness import segment_stiffness
from .cosserat import CosseratRobot, CosseratSolution, CosseratSolver, RodPiece, Tendon
from .statics import StaticSolver, StaticSolverOptions

Array = NDArray[np.float64]

MAX_BEND = math.pi / 2.0  # SPEC §1: θ ∈ [0°, 90°] per section


def _dense_tendon_jacobian(model, data) -> Array:
    """J_tendon (ntendon × nv), whether MuJoCo stores it sparse (row-compressed) or dense."""
    import mujoco

    if hasattr(model, "ten_J_rownnz"):
        dense = np.zeros((model.ntendon, model.nv))
        mujoco.mju_sparse2dense(dense, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind)
        return dense
    return np.asarray(data.ten_J).reshape(model.ntendon, model.nv)


class TendonStaticSolver(StaticSolver):
    """``StaticSolver`` plus known cable tensions: f += −Σ τ_c·J_c(q)ᵀ."""

    def __init__(self, model, data, tensions: Array, options=None) -> None:
        super().__init__(model, data, options)
        self.tensions = np.asarray(tensions, dtype=float)

    def solve(self, gravity, wrenches):
        """Equilibrium with gravity, wrenches *and tensions* ramped together (k/steps), each
        stage from the last; ramps as in the options, tried in turn until all stages converge."""
        import dataclasses

        full, start, options = self.tensions.copy(), self.data.qpos.copy(), self.options
        gravity, wrenches = np.asarray(gravity, dtype=float), np.asarray(wrenches, dtype=float)
        result = None
        try:
            self.options = dataclasses.replace(options, ramps=(1,))
            for steps in options.ramps:
                self.data.qpos[:] = start
                ok = True
                for k in range(1, steps + 1):
                    self.tensions = full * (k / steps)
                    result = super().solve(gravity * (k / steps), wrenches * (k / steps))
                    ok &= result.converged
                if ok:
                    break
            self.model.opt.gravity[:] = gravity
            self.data.xfrc_applied[:] = wrenches
        finally:
            self.tensions, self.options = full, options
        assert result is not None
        return dataclasses.replace(result, converged=bool(ok))

    def net_force(self, qpos, wrenches, loaded=None):
        f = super().net_force(qpos, wrenches, loaded)
        if np.any(self.tensions):
            self._mj.mj_tendon(self.model, self.data)
            f = f - self.tensions @ _dense_tendon_jacobian(self.model, self.data)
        return f


def section_geometry(geometry: ArmGeometry, sections: tuple[int, ...]) -> ArmGeometry:
    """``geometry`` keeping only the listed sections (base→tip order kept)."""
    return dataclasses.replace(geometry, sections=tuple(geometry.sections[k] for k in sections))


@dataclass(frozen=True)
class ArmPose:
    tip: Array  # (3,) last disk centre, base frame
    tip_axis: Array  # (3,) last disk z axis
    converged: bool

    @property
    def bend(self) -> float:
        """Angle (rad) between the tip axis and the base axis."""
        return float(math.acos(max(-1.0, min(1.0, self.tip_axis[2]))))


class ArmStatics:
    """The compiled arm (or some of its sections) solved under known cable tensions."""

    def __init__(self, geometry: ArmGeometry, options: ModelOptions) -> None:

        import mujoco

        from ..model.arm import build_single_arm_model

        self._mj = mujoco
        self.geometry = geometry
        self.options = options
        root = build_single_arm_model(geometry, options, tool="none", gravity=False)
        self.model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
        self.model.tendon_stiffness[:] = 0.0
        self.data = mujoco.MjData(self.model)
        tendons = [self.model.tendon(i).name for i in range(self.model.ntendon)]
        self.cables = [tendons.index(n) for n in model_names.arm_cable_names(model_names.SINGLE_ARM, geometry.n_sections)]
        n_disks = model_geometry(geometry, options).n_disks
        self.tip_body = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, model_names.scoped(model_names.SINGLE_ARM, model_names.disk(n_disks)))
        self.base_body = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, model_names.scoped(model_names.SINGLE_ARM, model_names.BASE_BODY))

    def solve(self, tensions: ArrayLike, gravity: ArrayLike = (0.0, 0.0, 0.0)) -> ArmPose:
        """Equilibrium under cable tensions (N, section-major, 3 per section) and gravity."""
        full = np.zeros(self.model.ntendon)
        full[self.cables] = np.asarray(tensions, dtype=float)
        solver = TendonStaticSolver(self.model, self.data, full, StaticSolverOptions(ramps=(1, 4, 16, 64)))
        self.data.qpos[:] = self.model.qpos0
        result = solver.solve(np.asarray(gravity, dtype=float), np.zeros((self.model.nbody, 6)))
        self._mj.mj_kinematics(self.model, self.data)
        base_pos = self.data.xpos[self.base_body]
        base_rot = self.data.xmat[self.base_body].reshape(3, 3)
        tip = base_rot.T @ (self.data.xpos[self.tip_body] - base_pos)
        axis = base_rot.T @ self.data.xmat[self.tip_body].reshape(3, 3)[:, 2]
        return ArmPose(tip, axis, result.converged)


def disk_masses(geometry: ArmGeometry, options: ModelOptions) -> list[tuple[float, float]]:
    """(s, kg) of every model disk from the design data: a section's disks (density × π R² t
    each, plus a rod backbone's mass) shared over the model's disks, at s = i·pitch."""
    model_geom = model_geometry(geometry, options)
    out = []
    s0 = 0.0
    for phys, sec in zip(geometry.sections, model_geom.sections):
        radius = phys.disk_diameter / 2.0
        mass = phys.n_segments * geometry.material.density * math.pi * radius**2 * geometry.disk_thickness
        if geometry.backbone == "rod":
            mass += geometry.rod.density * math.pi * geometry.rod.radius**2 * phys.length
        for i in range(1, sec.n_segments + 1):
            out.append((s0 + i * sec.pitch, mass / sec.n_segments))
        s0 += phys.length
    return out


def section_rigidities(geometry: ArmGeometry, scale: float = 1.0) -> list[tuple[float, float, float]]:
    """(EI_x, EI_y, GJ) per section, N·m², from ``model.stiffness`` (K_seg·pitch per axis)."""
    out = []
    for sec in geometry.sections:
        kx, ky, kz = segment_stiffness(geometry, sec)
        out.append((scale * kx * sec.pitch, scale * ky * sec.pitch, scale * kz * sec.pitch if math.isfinite(kz) else math.inf))
    return out


def cosserat_arm(geometry: ArmGeometry, options: ModelOptions, tensions: ArrayLike, gravity: ArrayLike = (0.0, 0.0, 0.0)) -> CosseratRobot:
    """The Cosserat description of ``geometry``'s sections under cable ``tensions``."""
    holes = geometry.cable_holes()
    gravity = np.asarray(gravity, dtype=float)
    pieces = tuple(
        RodPiece(sec.length, eix, eiy, gj, 0.0)
        for sec, (eix, eiy, gj) in zip(geometry.sections, section_rigidities(geometry, options.stiffness_scale))
    )
    ends = np.cumsum([sec.length for sec in geometry.sections])
    tendons = tuple(
        Tendon((float(holes[c, 0]), float(holes[c, 1])), float(ends[c // 3]), float(t))
        for c, t in enumerate(np.asarray(tensions, dtype=float))
        if t > 0.0
    )
    return CosseratRobot(pieces, tendons, tuple(float(g) for g in gravity), point_masses=tuple(disk_masses(geometry, options)))


def solve_cosserat(
    geometry: ArmGeometry, options: ModelOptions, tensions: ArrayLike, gravity: ArrayLike = (0.0, 0.0, 0.0)
) -> CosseratSolution:
    return CosseratSolver(cosserat_arm(geometry, options, tensions, gravity)).solve()


def max_single_tension(geometry: ArmGeometry, section: int, options: ModelOptions, cap: float = 150.0) -> float:
    """min(cap, τ bending ``section`` to 90°): τ·r·L/EI = π/2 with the section's mean EI."""
    eix, eiy, _ = section_rigidities(geometry, options.stiffness_scale)[section]
    sec = geometry.sections[section]
    return min(cap, MAX_BEND * 0.5 * (eix + eiy) / (geometry.cable_hole_radius * sec.length))


@dataclass(frozen=True)
class TendonComparison:
    label: str
    tensions: tuple[float, ...]
    gravity: tuple[float, ...]
    length: float
    tip_error_pct: float  # |tip_model − tip_cosserat| / L, %
    bend_model: float  # rad
    bend_reference: float  # rad
    converged: bool

    @property
    def bend_error_pct(self) -> float:
        """Bend per unit tension, model vs reference (the same tension divides both)."""
        if self.bend_reference < 1e-9:
            return 0.0
        return 100.0 * (self.bend_model / self.bend_reference - 1.0)


def compare(statics: ArmStatics, tensions: ArrayLike, gravity: ArrayLike, label: str = "") -> TendonComparison:
    tensions, gravity = np.asarray(tensions, dtype=float), np.asarray(gravity, dtype=float)
    pose = statics.solve(tensions, gravity)
    ref = solve_cosserat(statics.geometry, statics.options, tensions, gravity)
    ref_axis = ref.rotations[-1][:, 2]
    length = statics.geometry.length
    return TendonComparison(
        label=label,
        tensions=tuple(float(t) for t in tensions),
        gravity=tuple(float(g) for g in gravity),
        length=length,
        tip_error_pct=float(100.0 * np.linalg.norm(pose.tip - ref.tip) / length),
        bend_model=pose.bend,
        bend_reference=float(math.acos(max(-1.0, min(1.0, ref_axis[2])))),
        converged=pose.converged and ref.converged,
    )
