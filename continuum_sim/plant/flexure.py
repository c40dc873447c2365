"""The flexure segments' nonlinear passive torque, added to MuJoCo's linear joint springs every step.

``model.flexure_model = "nonlinear"`` (docs/model.md, "Flexures beyond linear"): the MJCF
keeps each hinge's linear stiffness (the initial slope, ``model.stiffness``) and this
effect adds the remainder τ_nl(q) − k·q of the segment's moment–rotation curve computed by
the geometrically exact leaf model (``plant.leaf_rod``). Per section, one table of the
remainder moment (x, y) over a polar grid of the per-segment rotation s = (s_x, s_y): the
three leaves' tables summed at angles φ − α_i (3-fold, direction-dependent: the leaf that
is compressed buckles first). Beyond the table's largest rotation the remainder continues
along its last slope.

Bending in two axes: a hinge pair's angles (a, b) are taken as the rotation vector's
in-plane components s = a·e₁ + b·e₂ (the axes of its two hinges in the disk frame), the
same small-rotation reading the linear springs ½k(a² + b²) make; the twist a universal
joint adds (a·b/2, second order) is not a bending load. A ball joint: the (x, y) part of
its quaternion's rotation vector, the torque on its x and y dofs (its twist spring stays
MuJoCo's). A model joint standing for
n_phys/n_model physical segments in series turns each by c·q (c = n_model/n_phys) and
carries the same moment, so its torque is scale·M(c·q).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..configio import ConfigError
from ..model import names
from ..model.names import scoped
from ..model.stiffness import segment_stiffness
from .leaf_rod import leaf_table, section_segment

if TYPE_CHECKING:
    import mujoco

    from ..geometry import ArmGeometry, SectionGeometry

THETA_MAX_DEG = 16.0  # per physical segment: the sections' 90° max bend is 9° per segment
THETA_STEP_DEG = 1.0
PHI_STEP_DEG = 15.0  # divides 120°: every leaf angle φ − α_i falls on the leaf grid


@dataclass(frozen=True)
class SectionCurve:
    """A section's remainder moment ΔM(s) = M_nl(s) − K·s (N·m) on a polar grid of the per-segment rotation."""

    theta: np.ndarray  # (n_theta,) rad, uniform from 0
    phi: np.ndarray  # (n_phi,) rad, uniform over [0, 2π)
    remainder: np.ndarray  # (n_phi, n_theta, 2) segment-frame (x, y)
    linear: tuple[float, float]  # K_x, K_y (N·m/rad): the MJCF springs' per-segment stiffness

    def moment(self, s: np.ndarray) -> np.ndarray:
        """The nonlinear moment M(s) (N·m) of one segment, s = (s_x, s_y) rad (for tests and plots)."""
        rem = np.zeros(2)
        _interp(self.remainder, self.theta[1], self.phi[1], float(s[0]), float(s[1]), rem)
        return np.array([self.linear[0] * s[0], self.linear[1] * s[1]]) + rem


def section_curve(geometry: ArmGeometry, section: SectionGeometry) -> SectionCurve:
    """The nonlinear curve of ``section``'s segments, from the leaf model's table (cached)."""
    step = math.radians(PHI_STEP_DEG)
    n_psi = int(round(180.0 / PHI_STEP_DEG)) + 1
    n_theta = int(round(THETA_MAX_DEG / THETA_STEP_DEG)) + 1
    theta, _psi, leaf = leaf_table(section_segment(geometry, section), math.radians(THETA_MAX_DEG), n_theta, n_psi)
    n_phi = int(round(360.0 / PHI_STEP_DEG))
    phi = np.arange(n_phi) * step
    total = np.zeros((n_phi, n_theta, 2))
    for alpha_deg in section.leaf_angles_deg:
        if abs(alpha_deg / PHI_STEP_DEG - round(alpha_deg / PHI_STEP_DEG)) > 1e-9:
            raise ConfigError("model.flexure_model", f"nonlinear needs leaf angles on a {PHI_STEP_DEG:g}° grid (got {alpha_deg:g})")
        a = math.radians(alpha_deg)
        c, s = math.cos(a), math.sin(a)
        for k in range(n_phi):
            psi_deg = (k * PHI_STEP_DEG - alpha_deg + 180.0) % 360.0 - 180.0  # (−180, 180]
            mirror = abs(psi_deg) > 90.0 + 1e-9
            if mirror:  # (s_x, s_y) → (−s_x, s_y): ψ → 180° − ψ, moment (−M_x, M_y)
                psi_deg = (180.0 - psi_deg + 180.0) % 360.0 - 180.0
            j = int(round((psi_deg + 90.0) / PHI_STEP_DEG))
            local = leaf[j].copy()
            if mirror:
                local[:, 0] *= -1.0
            total[k, :, 0] += c * local[:, 0] - s * local[:, 1]
            total[k, :, 1] += s * local[:, 0] + c * local[:, 1]
    total[:, 0, :] = 0.0  # no moment at zero rotation (the solver's values there are difference noise, ~1e-13 N·m)
    kx, ky, _ = segment_stiffness(geometry, section)
    direction = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    linear = theta[None, :, None] * direction[:, None, :] * np.array([kx, ky])
    return SectionCurve(theta, phi, total - linear, (kx, ky))


@njit(cache=True)
def _interp(table: np.ndarray, dtheta: float, dphi: float, sx: float, sy: float, out: np.ndarray) -> None:
    """Bilinear remainder at s = (sx, sy) into ``out`` (2,); linear continuation past the last θ."""
    n_phi, n_theta = table.shape[0], table.shape[1]
    theta = math.sqrt(sx * sx + sy * sy)
    phi = math.atan2(sy, sx)
    if phi < 0.0:
        phi += 2.0 * math.pi
    u = phi / dphi
    k0 = int(u)
    fk = u - k0
    k0 = k0 % n_phi
    k1 = (k0 + 1) % n_phi
    v = theta / dtheta
    j0 = min(int(v), n_theta - 2)
    fj = v - j0  # > 1 past the table: linear continuation of the last interval
    for d in range(2):
        a = table[k0, j0, d] + fj * (table[k0, j0 + 1, d] - table[k0, j0, d])
        b = table[k1, j0, d] + fj * (table[k1, j0 + 1, d] - table[k1, j0, d])
        out[d] = a + fk * (b - a)


@njit(cache=True)
def flexure_forces(qpos: np.ndarray, qfrc: np.ndarray, last: np.ndarray, qadr: np.ndarray, dofadr: np.ndarray,
                   axes: np.ndarray, factor: np.ndarray, scale: np.ndarray, curve: np.ndarray, tables: np.ndarray,
                   dtheta: float, dphi: float) -> None:
    """Put every hinge pair's remainder torque into ``qfrc``, replacing the share ``last`` (n_pairs, 2) added before.

    Pair p: hinges at qpos ``qadr[p]`` (2,), dofs ``dofadr[p]`` (2,), axes (2, 2) in the disk
    frame, rotation factor c, torque scale, and its section's table ``tables[curve[p]]``. A
    ball joint has ``qadr[p] = (quaternion address, −1)``, dofs (x, y) of its three, axes the identity.
    """
    rem = np.zeros(2)
    for p in range(qadr.shape[0]):
        c = factor[p]
        if qadr[p, 1] < 0:  # a ball joint: its quaternion's rotation vector (x, y); dofs = local x, y
            w, vx, vy, vz = qpos[qadr[p, 0]], qpos[qadr[p, 0] + 1], qpos[qadr[p, 0] + 2], qpos[qadr[p, 0] + 3]
            norm = math.sqrt(vx * vx + vy * vy + vz * vz)
            if w < 0.0:
                w, vx, vy, norm = -w, -vx, -vy, norm
            k = 2.0 * math.atan2(norm, w) / norm if norm > 1e-12 else 2.0
            sx, sy = c * k * vx, c * k * vy
        else:
            a, b = qpos[qadr[p, 0]], qpos[qadr[p, 1]]
            sx = c * (a * axes[p, 0, 0] + b * axes[p, 1, 0])
            sy = c * (a * axes[p, 0, 1] + b * axes[p, 1, 1])
        _interp(tables[curve[p]], dtheta, dphi, sx, sy, rem)
        for h in range(2):
            tau = -scale[p] * (rem[0] * axes[p, h, 0] + rem[1] * axes[p, h, 1])
            qfrc[dofadr[p, h]] += tau - last[p, h]
            last[p, h] = tau


@dataclass
class FlexureEffect:
    """The remainder torques of every flexure hinge pair of a compiled model (both arms), for one MjData.

    ``apply(data)`` before every ``mj_step`` writes them into ``data.qfrc_applied`` from the
    step's starting positions (explicit in time, like any applied force), replacing its own
    share of the step before (``last``) so other users of ``qfrc_applied`` keep theirs.
    """

    qadr: np.ndarray
    dofadr: np.ndarray
    axes: np.ndarray
    factor: np.ndarray
    scale: np.ndarray
    curve: np.ndarray
    tables: np.ndarray
    dtheta: float
    dphi: float
    last: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    def __post_init__(self) -> None:
        self.last = np.zeros((len(self.qadr), 2))

    def apply(self, data: mujoco.MjData) -> None:
        """Add the torques for ``data``'s positions to ``data.qfrc_applied`` (own share replaced)."""
        flexure_forces(data.qpos, data.qfrc_applied, self.last, self.qadr, self.dofadr, self.axes, self.factor,
                       self.scale, self.curve, self.tables, self.dtheta, self.dphi)

    def torques(self, qpos: np.ndarray, nv: int) -> np.ndarray:
        """The remainder generalized forces (nv,) at ``qpos`` alone (tests, statics)."""
        out = np.zeros(nv)
        flexure_forces(np.asarray(qpos, dtype=float), out, np.zeros_like(self.last), self.qadr, self.dofadr, self.axes,
                       self.factor, self.scale, self.curve, self.tables, self.dtheta, self.dphi)
        return out


def flexure_effect(model: mujoco.MjModel, arms: tuple[str, ...], geometry: ArmGeometry, model_geometry: ArmGeometry,
                   scale: float) -> FlexureEffect:
    """The effect for every flexure joint of ``arms`` (hinge pairs ``joint_<i>_x``/``_y`` or ball ``joint_<i>``).

    ``geometry`` is the physical arm (the leaf tables), ``model_geometry`` the resampled one
    (joints per section); ``scale`` is ``model.stiffness_scale`` (each section's own
    ``stiffness_scale`` multiplies it, as it does the springs).
    """
    import mujoco

    curves = [section_curve(geometry, s) for s in geometry.sections]
    tables = np.stack([c.remainder for c in curves])
    qadr, dofadr, axes, factor, curve, scales = [], [], [], [], [], []
    for arm in arms:
        index = 0
        for si, (phys, mod) in enumerate(zip(geometry.sections, model_geometry.sections)):
            for _ in range(mod.n_segments):
                index += 1
                ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, scoped(arm, names.joint(index, a))) for a in "xy"]
                ball = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, scoped(arm, names.joint(index)))
                if min(ids) >= 0:
                    qadr.append([int(model.jnt_qposadr[j]) for j in ids])
                    dofadr.append([int(model.jnt_dofadr[j]) for j in ids])
                    axes.append([np.asarray(model.jnt_axis[j][:2], dtype=float) for j in ids])
                elif ball >= 0 and model.jnt_type[ball] == mujoco.mjtJoint.mjJNT_BALL:
                    qadr.append([int(model.jnt_qposadr[ball]), -1])
                    dofadr.append([int(model.jnt_dofadr[ball]), int(model.jnt_dofadr[ball]) + 1])
                    axes.append([np.array([1.0, 0.0]), np.array([0.0, 1.0])])
                else:
                    raise ConfigError("model.flexure_model", f"no joint {scoped(arm, names.joint(index))} (hinge pair or ball) in the model")
                factor.append(mod.n_segments / phys.n_segments)
                curve.append(si)
                scales.append(scale * phys.stiffness_scale)  # as the joint springs (model.stiffness.joint_stiffnesses)
    return FlexureEffect(np.array(qadr, dtype=np.int64), np.array(dofadr, dtype=np.int64), np.array(axes, dtype=float),
                         np.array(factor, dtype=float), np.array(scales, dtype=float), np.array(curve, dtype=np.int64),
                         tables, float(curves[0].theta[1]), float(curves[0].phi[1]))
