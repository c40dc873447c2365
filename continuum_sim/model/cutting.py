"""Cutting foam: voxel material, a material-removal cutting force, connectivity detachment.

The plate's rigid geoms (``scene.py``) only carry the gripper and the clamp; what the
cutter meets is ``FoamGrid``, a boolean voxel grid over every part of the plate the
cutter can reach (the whole plate outside the clamped strip, sample included) at
``FoamOptions.voxel_size``. ``FoamCutter`` runs before every physics step:

* **Engagement.** The cutter is a cylinder of radius R (``<arm>/grinder/cutter``, axis ≈
  the plate normal). Its feed velocity v_f is the housing's velocity at the cutter centre
  in the plate plane. On the leading half circle it samples the remaining material depth
  a(θ) (voxel columns, overlap with the cutter's axial extent) at ``engagement_points``
  angles θ from the feed direction.
* **Force (mechanistic milling model, Altintas, *Manufacturing Automation*, 2nd ed., 2012,
  ch. 2).** Chip thickness h(θ) = c·cos θ with c = 2π·v_f/ω the feed per revolution (one
  effective edge: an abrasive burr has no countable teeth; the mean force does not depend
  on the number of edges). Per unit edge length the tangential force is K_t·h and the
  radial one K_r·h; averaged over a revolution the force on the cutter is
  F = −(v_f/ω)·Σ_k a_k [K_r·(e_f·I_cc + e_n·I_cs) + s·K_t·(−e_f·I_cs + e_n·I_cc)] with the
  exact bin integrals I_cc = ∫cos²θ dθ, I_cs = ∫cos θ sin θ dθ (e_n = z × e_f, s the
  spin sense), and the spindle torque T = (v_f/ω)·K_t·R·Σ a_k ∫cos θ dθ. So the cutting
  power is T·ω = K_t·v_f·A = u·MRR with A = R·Σ a_k ∫cos θ dθ the swept cross-section:
  K_t *is* the specific cutting energy u, and F_t = P/(ω·R). A full slot (a constant)
  gives |F_normal| = (π/4)·F_t and |F_feed| = (π/4)·(K_r/K_t)·F_t.
* **Removal.** Voxels whose centres lie inside the cutter are removed (cut) while the
  spindle turns at least ``min_cutting_speed`` and is not stalled.
* **A cutter that does not cut** (spindle off or stalled) is pushed out of the remaining
  material by a spring-damper on the equivalent flat-face penetration (``block_*``).
* **Spindle.** ``tools.SpindleLoop`` (PI, torque limit, stall) sets the spindle actuator;
  the cutting torque loads the spindle joint (``qfrc_applied``), so it slows under load.
* **Detachment.** Every ``connectivity_period`` after material was removed, the grid's
  face connectivity is checked (numpy path: ``scipy.ndimage.label``; native: a flood fill
  from the held material that stops at the clamped edge); the sample comes free when the
  material under the gripper's jaws (voxels within ``grip_radius`` of the grasp point) is
  no longer connected to the clamped edge. Then the weld ``sample_weld`` is released and
  every voxel that lost its connection leaves the grid (it went with the sample).

Each step (spindle loop, near test, engagement, force with the implicit feed, removal,
wrench, and the observer's sums) runs as one numba kernel, and the connectivity check as
another (``cutting_kernels``), unless ``FoamOptions.native`` is false; both paths give
bit-identical results. (A cutter pressed into material while not cutting, the block spring, takes the
Python path in either case.)

The forces are added to ``xfrc_applied``/``qfrc_applied`` (what was added the step before
is taken back first), so other per-step models may add theirs.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from scipy import ndimage

from . import cutting_kernels as ck
from .scene_options import FoamOptions
from .tools import CUTTER_GEOM, GRINDER, SPINDLE_JOINT, SpindleLoop, ToolOptions


class FoamGrid:
    """Boolean voxels of the cuttable plate: ``material[i, j, k]`` (x, y, z), anchor at i = 0."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, voxel_size: float) -> None:
        self.lo = np.asarray(lo, float)
        self.hi = np.asarray(hi, float)
        self.shape = tuple(max(1, math.ceil(float(e) / voxel_size - 1e-9)) for e in self.hi - self.lo)
        self.h = (self.hi - self.lo) / np.array(self.shape)
        self.material = np.ones(self.shape, dtype=bool)
        self.cut = np.zeros(self.shape, dtype=bool)  # removed by the cutter (not: left with the sample)
        self.removed_at = np.full(self.shape[:2], np.nan, dtype=np.float32)  # first removal per column (s)
        self.centres = [self.lo[a] + (np.arange(n) + 0.5) * self.h[a] for a, n in enumerate(self.shape)]

    @property
    def voxel_volume(self) -> float:
        return float(np.prod(self.h))

    def reset(self) -> None:
        self.material[...] = True
        self.cut[...] = False
        self.removed_at[...] = np.nan

    def cut_map(self) -> np.ndarray:
        """Fraction of each column's voxels the cutter removed (2-D, x by y): the kerf seen from above."""
        return self.cut.mean(axis=2)

    def index_range(self, axis: int, a: float, b: float) -> tuple[int, int]:
        """[i0, i1) of the voxels whose centres may lie in [a, b] along ``axis``."""
        i0 = math.floor((a - self.lo[axis]) / self.h[axis] - 0.5)
        i1 = math.ceil((b - self.lo[axis]) / self.h[axis] + 0.5)
        n = self.shape[axis]
        return max(0, i0), min(n, i1)

    def layer_weights(self, z0: float, z1: float) -> np.ndarray:
        """Length (m) of each z layer inside [z0, z1]."""
        edges = self.lo[2] + np.arange(self.shape[2] + 1) * self.h[2]
        return np.clip(np.minimum(edges[1:], z1) - np.maximum(edges[:-1], z0), 0.0, None)

    def depth_at(self, x: np.ndarray, y: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """Material depth (m) in the columns holding the points (x, y), weighted per layer."""
        i = np.floor((x - self.lo[0]) / self.h[0]).astype(int)
        j = np.floor((y - self.lo[1]) / self.h[1]).astype(int)
        inside = (i >= 0) & (i < self.shape[0]) & (j >= 0) & (j < self.shape[1])
        depth = np.zeros(x.shape)
        if inside.any():
            depth[inside] = self.material[i[inside], j[inside], :] @ weights
        return depth


@dataclass
class CutState:
    """What the cutter did in the last step (recorded per tick; SI units)."""

    force: np.ndarray = field(default_factory=lambda: np.zeros(3))  # on the cutter, world frame
    feed_force: float = 0.0  # along −feed (resisting), N
    normal_force: float = 0.0  # across the feed, N (signed along z × feed)
    torque: float = 0.0  # cutting torque on the spindle, N·m
    mrr: float = 0.0  # m³/s
    power: float = 0.0  # W
    depth: float = 0.0  # mean engaged depth over the leading half circle, m
    chip: float = 0.0  # feed per revolution, m
    feed_speed: float = 0.0  # m/s
    cutting: bool = False  # spindle fast enough and material engaged
    blocked: bool = False  # a non-cutting cutter pressed into material


_IDLE = CutState()  # what ``FoamCutter.step`` returns when nothing happened (all zero; shared, read only)
_IDLE.force.flags.writeable = False


class FoamCutter:
    """Voxel foam + cutting force + spindle loop + connectivity detachment (see module doc)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        grid: FoamGrid,
        foam: FoamOptions,
        tools: ToolOptions,
        density: float,
        grasp_point: np.ndarray,
        sample_box: tuple[np.ndarray, np.ndarray],
        arm: str = "left",
        kerf: tuple[np.ndarray, float] | None = None,
    ) -> None:
        """``kerf`` (planned centre polyline, width) defines the kerf band the ``cells_*``
        views count (the planned cut, for progress reports); the material is the whole grid."""
        from .scene import KERF_BAND, SAMPLE_BODY, SAMPLE_WELD

        self.model, self.data, self.grid, self.foam, self.tools = model, data, grid, foam, tools
        self.u = foam.cutting_energy(density)
        self.cutter = _id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{arm}/{GRINDER}/{CUTTER_GEOM}")
        self.body = int(model.geom_bodyid[self.cutter])
        spindle = _id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{arm}/{GRINDER}/{SPINDLE_JOINT}")
        self.spindle_dof = int(model.jnt_dofadr[spindle])
        self.spindle_actuator = _id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{arm}/{GRINDER}/{SPINDLE_JOINT}")
        self.weld = _id(model, mujoco.mjtObj.mjOBJ_EQUALITY, SAMPLE_WELD)
        self.sample_body = _id(model, mujoco.mjtObj.mjOBJ_BODY, SAMPLE_BODY)
        band = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in KERF_BAND]
        self._band = np.array([g for g in band if g >= 0], dtype=int)
        self._band_alpha = model.geom_rgba[self._band, 3].copy()
        self.radius = float(model.geom_size[self.cutter, 0])
        self.half_length = float(model.geom_size[self.cutter, 1])
        self.spindle_inertia = float(model.dof_armature[self.spindle_dof] + model.body_inertia[model.dof_bodyid[self.spindle_dof], 2])
        k = foam.engagement_points
        edges = np.linspace(-math.pi / 2, math.pi / 2, k + 1)
        self._theta = 0.5 * (edges[1:] + edges[:-1])
        a, b = edges[:-1], edges[1:]
        self._i_c = np.sin(b) - np.sin(a)  # ∫cos θ
        self._i_cc = (b - a) / 2 + (np.sin(2 * b) - np.sin(2 * a)) / 4  # ∫cos² θ
        self._i_cs = (np.sin(b) ** 2 - np.sin(a) ** 2) / 2  # ∫cos θ sin θ
        # Sample one voxel beyond the edge: the voxel holding the point then has its centre
        # outside the cutter now and ahead of it, so it was never swept before.
        self._probe = self.radius + float(np.max(grid.h[:2]))
        # Recent cutter centres: a probe point inside the probe circle of any of them was
        # reached before (the cutter jittered back and forth), so no chip is there — finer
        # than the voxels can tell. Older history is the voxels'.
        n_recent = max(2, math.ceil(foam.recent_window / float(model.opt.timestep)))
        self._recent = np.full((n_recent, 2), np.inf)
        self._probe2 = (self._probe - 1e-9) ** 2
        self._cos_t, self._sin_t = np.cos(self._theta), np.sin(self._theta)
        self._z_mid = 0.5 * float(grid.lo[2] + grid.hi[2])
        self._root = int(model.body_rootid[self.body])
        self._jac = np.zeros((3, model.nv))
        self._minv_jt = np.zeros((2, model.nv))
        # Held region: the sample's columns within grip_radius of the grasp point.
        gx, gy = np.meshgrid(grid.centres[0], grid.centres[1], indexing="ij")
        lo, hi = sample_box
        in_sample = (gx >= lo[0]) & (gx <= hi[0]) & (gy >= lo[1]) & (gy <= hi[1])
        near = (gx - grasp_point[0]) ** 2 + (gy - grasp_point[1]) ** 2 <= foam.grip_radius**2
        self._held_columns = in_sample & near if (in_sample & near).any() else in_sample
        self._held_flat = np.flatnonzero(self._held_columns).astype(np.int64)  # flat (i, j) indices, native check
        band = np.zeros(grid.shape[:2], dtype=bool)  # type: ignore[assignment]
        if kerf is not None:
            # The kerf's core: the middle half of its width, so a cut up to a quarter kerf width
            # off the plan still clears every "cell".
            line, width = np.asarray(kerf[0], float)[:, :2], 0.5 * float(kerf[1])
            for a, b in itertools.pairwise(line):
                ab = b - a
                t = np.clip(((gx - a[0]) * ab[0] + (gy - a[1]) * ab[1]) / float(ab @ ab), 0.0, 1.0)
                band |= (gx - a[0] - t * ab[0]) ** 2 + (gy - a[1] - t * ab[1]) ** 2 <= (width / 2) ** 2
        self._band_columns = band
        self._band_flat = np.flatnonzero(band).astype(np.int64)  # the band's columns in material.reshape(-1, nz)
        self.spindle = SpindleLoop(tools)
        self._edges = grid.lo[2] + np.arange(grid.shape[2] + 1) * grid.h[2]  # z layer edges (as layer_weights)
        self._native = _compiled_kernels() if foam.native else None
        # Per-step reads and writes go through views made once (each ``data.<field>`` access
        # builds a new array object): MjData's buffers live as long as ``data``.
        self._opt = model.opt
        self._qvel, self._ctrl, self._qacc, self._qfrc = data.qvel, data.ctrl, data.qacc, data.qfrc_applied
        self._xpos_row, self._xmat_row = data.geom_xpos[self.cutter], data.geom_xmat[self.cutter]
        self._cvel_row, self._com_row = data.cvel[self.body], data.subtree_com[self._root]
        self._xipos_row, self._xfrc_row = data.xipos[self.body], data.xfrc_applied[self.body]
        self._box = (*(float(v) for v in grid.lo), *(float(v) for v in grid.hi))
        self._point = np.array([0.0, 0.0, self._z_mid])  # where the cutting force acts (mj_jac)
        self._jxy = self._jac[:2]
        self._e, self._g = np.zeros(2), np.zeros(2)
        self._wrench, self._delta = np.zeros(6), np.zeros(6)
        self._applied_force = np.zeros(6)
        self._fv: np.ndarray | None = None
        self._native_tick: Any = None
        self._scratch_acc = np.zeros(ck.N_A)  # ``step``'s sums (nobody reads them)
        if self._native is not None:
            self._fuse(data, self._native)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Uncut plate, welded sample, idle spindle (the MuJoCo state is the caller's)."""
        self.grid.reset()
        self.spindle.reset()
        self.model.geom_rgba[self._band, 3] = self._band_alpha
        self.data.eq_active[self.weld] = 1
        self._removed_volume = 0.0
        self.state = CutState()
        self.detach_time: float | None = None
        self.removed_volume = 0.0
        self.freed_volume = 0.0  # material that left with the sample
        self._applied_force[:] = 0.0
        self._applied_torque = 0.0
        self._dirty = False
        self._last_check = -math.inf
        self._recent[:] = np.inf
        self._recent_i = 0
        if self._fv is not None:
            self._fv[ck.F_TORQUE_APPLIED] = 0.0
            self._fv[ck.F_DIRTY] = self._fv[ck.F_UNBLOCK] = 0.0
            self._iv[ck.I_RI] = 0
        self._block: tuple[float, float, float, float, float] | None = None
        self.checks = 0

    @property
    def detached(self) -> bool:
        return self.detach_time is not None

    # The fused native step (``cutting_kernels._tick``) keeps these in its slots.
    @property
    def removed_volume(self) -> float:
        """Material the cutter removed (m³)."""
        fv = self._fv
        return self._removed_volume if fv is None else fv.item(ck.F_REMOVED)

    @removed_volume.setter
    def removed_volume(self, value: float) -> None:
        if self._fv is None:
            self._removed_volume = value
        else:
            self._fv[ck.F_REMOVED] = value

    @property
    def state(self) -> CutState:
        """What the cutter did in the last step; after a fused step built only when read."""
        fv = self._fv
        if fv is not None and fv[ck.F_LAZY] != 0.0:
            fv[ck.F_LAZY] = 0.0
            self._state = self._fused_state(fv)
        return self._state

    @state.setter
    def state(self, value: CutState) -> None:
        self._state = value
        if self._fv is not None:
            self._fv[ck.F_LAZY] = 0.0

    @staticmethod
    def _fused_state(fv: np.ndarray) -> CutState:
        """The CutState of the fused step's outputs ``fv[F_OUT:]``."""
        kind = fv[ck.F_KIND]
        if kind == 0.0:
            return _IDLE
        if kind == 1.0:
            fx, fy, feed_force, normal_force, torque, mrr, power, depth, chip, speed, cutting = fv[ck.F_OUT:ck.F_KIND].tolist()
            return CutState(force=np.array([fx, fy, 0.0]), feed_force=feed_force, normal_force=normal_force,
                            torque=torque, mrr=mrr, power=power, depth=depth, chip=chip, feed_speed=speed,
                            cutting=cutting != 0.0)
        state = CutState()
        state.cutting = True
        return state

    # Progress views over the planned kerf band's voxel columns (what the kerf cells were).
    @property
    def n_cells(self) -> int:
        """Voxel columns of the planned kerf's core (the middle half of its width)."""
        return int(np.count_nonzero(self._band_columns))

    @property
    def cells_remaining(self) -> int:
        """Kerf-band columns with material left in them."""
        material = self.grid.material
        if self._native is not None:  # (read every few ticks by the recorder)
            return int(self._native["columns_with_material"](material, self._band_flat))
        return int(np.count_nonzero(material.reshape(-1, material.shape[2])[self._band_flat].any(axis=1)))

    @property
    def removal_time(self) -> np.ndarray:
        """First cut (s) of each kerf-band column (NaN: never cut)."""
        return self.grid.removed_at[self._band_columns].astype(float)

    @property
    def stalled(self) -> bool:
        return self.spindle.stalled

    @property
    def spindle_speed(self) -> float:
        return float(self.data.qvel[self.spindle_dof])

    # ------------------------------------------------------------------ step
    def step(self, spindle_reference: float) -> CutState:
        """Before one ``mj_step``: spindle set-point, cutting force and torque, removal.

        Natively one kernel call (``tick``); else the spindle loop and ``_step`` in Python."""
        if self._native_tick is not None:
            self.tick(spindle_reference, self._scratch_acc)
            return self.state
        data = self.data
        dt = float(self._opt.timestep)
        omega = self._qvel.item(self.spindle_dof)
        time = float(data.time)
        self._ctrl[self.spindle_actuator] = self.spindle.control(spindle_reference, omega, time, dt)
        return self._step(omega, dt)

    def tick(self, spindle_reference: float, acc: np.ndarray) -> None:
        """``step``, its CutState added to the sums ``acc`` (``cutting_kernels.N_A`` slots:
        ``CuttingObserver``'s, in its order). It runs every physics step: natively one call
        of ``cutting_kernels._tick`` (the spindle loop included; the CutState is built only
        if ``state`` is read), the Python path only where the kernel declines."""
        native = self._native_tick
        if native is None:
            before = self.removed_volume
            _add(acc, self.step(spindle_reference), self.removed_volume > before)
            return
        grid = self.grid
        flags = native(grid.material, grid.cut, grid.removed_at, self._recent, self._fv, self._iv, acc,
                       spindle_reference, self.data.time, self._opt.timestep)
        if flags:
            self._declined(flags, acc)

    def _declined(self, flags: int, acc: np.ndarray) -> None:
        """After ``_tick``: the stall event it tripped, and the step it left to the Python path
        (near the material, not cutting) with the fused step's state."""
        fv, iv = self._fv, self._iv
        assert fv is not None
        omega = fv.item(ck.F_OMEGA)
        if flags & ck.TICK_STALL:
            self.spindle.events.append((fv.item(ck.F_TIME), "stall", omega))
        if flags & ck.TICK_PYTHON:
            if fv[ck.F_UNBLOCK] != 0.0:  # a fused step ran since the last Python one: no contact then
                fv[ck.F_UNBLOCK] = 0.0
                self._block = None
            self._recent_i, self._applied_torque = int(iv[ck.I_RI]), float(fv[ck.F_TORQUE_APPLIED])
            before = self.removed_volume
            state = self._step(omega, fv.item(ck.F_DT))
            iv[ck.I_RI], fv[ck.F_TORQUE_APPLIED] = self._recent_i, self._applied_torque
            _add(acc, state, self.removed_volume > before)

    def _step(self, omega: float, dt: float) -> CutState:
        """``step`` after the spindle's set-point, in Python (``native`` false, and the native
        path's non-cutting contact)."""
        data, grid, foam = self.data, self.grid, self.foam
        state = _IDLE
        px_, py_, pz_ = self._xpos_row.tolist()
        mat = self._xmat_row.tolist()
        ax, ay, az = mat[2], mat[5], mat[8]  # the cutter axis (matrix column z)
        z_mid = self._z_mid
        # The axis point at the plate's mid-plane (the cutter stands near the plate normal).
        along = (z_mid - pz_) / az if abs(az) > 0.5 else 0.0
        cx, cy = px_ + along * ax, py_ + along * ay
        z0 = pz_ - self.half_length * abs(az)
        z1 = pz_ + self.half_length * abs(az)
        recent, ri = self._recent, self._recent_i
        recent[ri, 0] = cx  # (its own probe circle excludes nothing: strict < below)
        recent[ri, 1] = cy
        r, probe = self.radius, self._probe
        lo0, lo1, lo2, hi0, hi1, hi2 = self._box
        near = cx + probe > lo0 and cx - probe < hi0 and cy + probe > lo1 and cy - probe < hi1 and z1 > lo2 and z0 < hi2
        fx = fy = 0.0
        torque = 0.0
        if not near:
            self._block = None
        else:
            lo = grid.lo
            # Velocity of the cutter centre: the body's spatial velocity (cvel, about the
            # subtree centre of mass of its tree's root) moved to the point.
            w0, w1, w2, w3, w4, _ = self._cvel_row.tolist()
            o0, o1, o2 = self._com_row.tolist()
            rx, ry, rz = px_ - o0, py_ - o1, pz_ - o2
            vx = w3 + w1 * rz - w2 * ry
            vy = w4 + w2 * rx - w0 * rz
            speed = math.hypot(vx, vy)
            cutting = abs(omega) >= foam.min_cutting_speed and not self.spindle.stalled
            feeding = cutting and speed > 1e-6
            ex, ey = (vx / speed, vy / speed) if feeding else (0.0, 0.0)  # feed direction; e_n = z × e_f = (−ey, ex)
            if self._native is not None:
                n_inside, d_cc, d_cs, d_c, mean_depth = self._native["engage"](
                    grid.material, *grid.centres, self._edges, lo, grid.h, recent, self._cos_t, self._sin_t,
                    self._i_cc, self._i_cs, self._i_c, cx, cy, z0, z1, r, probe, self._probe2, ex, ey, feeding)
            else:
                overlap = self._overlap(cx, cy, z0, z1)
                n_inside = int(np.count_nonzero(overlap[-1]))
                if feeding:
                    ct, st = self._cos_t, self._sin_t
                    qx = cx + probe * (ex * ct - ey * st)
                    qy = cy + probe * (ey * ct + ex * st)
                    depth = grid.depth_at(qx, qy, overlap[0])
                    reached = (((qx[:, None] - recent[None, :, 0]) ** 2 + (qy[:, None] - recent[None, :, 1]) ** 2)
                               < self._probe2).any(axis=1)
                    depth[reached] = 0.0
                    d_cc, d_cs, d_c = float(depth @ self._i_cc), float(depth @ self._i_cs), float(depth @ self._i_c)
                    mean_depth = float(depth.mean())
            if feeding:
                sgn = 1.0 if omega > 0 else -1.0
                k_t = self.u
                k_r = k_t * foam.radial_ratio
                # F = −(v_f/ω)·[K_r·(e_f I_cc + e_n I_cs) + s·K_t·(−e_f I_cs + e_n I_cc)], linear in
                # the velocity: F = −D·v with D = [[a, −b], [b, a]] (a: against the feed, b: across).
                a = (k_r * d_cc - sgn * k_t * d_cs) / abs(omega)
                bb = (k_r * d_cs + sgn * k_t * d_cc) / abs(omega)
                # The force is −s·g with s the feed speed along e_f and g = a·e_f + b·e_n: a stiff
                # damper on a light tool (a·dt/m ≈ 1 at twice the default foam density); applied
                # explicitly it diverges. Backward Euler on s instead: s' = e_f·w / (1 + dt·e_f·L·g),
                # w = v + dt·a_other, with L the cutter point's inverse inertia (J M⁻¹ Jᵀ) and
                # a_other the acceleration of everything else (last step's, less this force's
                # share): exact when steady. The foam only resists: s' ≥ 0.
                feed = self._implicit_feed(vx, vy, ex, ey, a, bb, dt, cx, cy)
                fx = -feed * (a * ex - bb * ey)
                fy = -feed * (a * ey + bb * ex)
                c = feed / abs(omega)  # feed per radian: v_f/ω = c/(2π)
                area = r * d_c
                torque = c * k_t * area  # = u·v_f·A/ω
                state = CutState(
                    force=np.array([fx, fy, 0.0]), feed_force=-(fx * ex + fy * ey), normal_force=-fx * ey + fy * ex,
                    torque=torque, mrr=feed * area, power=torque * abs(omega), depth=mean_depth,
                    chip=2 * math.pi * c, feed_speed=speed, cutting=area > 0.0,
                )
            if n_inside and cutting:
                if self._native is not None:
                    self._native["remove"](grid.material, grid.cut, grid.removed_at, *grid.centres, lo, grid.h,
                                           cx, cy, z0, z1, r, float(data.time))
                else:
                    weights, i0, i1, j0, j1, k0, k1, dx, dy, inside = overlap
                    grid.material[i0:i1, j0:j1, k0:k1][inside] = False
                    grid.cut[i0:i1, j0:j1, k0:k1][inside] = True
                    cols = grid.removed_at[i0:i1, j0:j1]
                    hit = inside.any(axis=2) & np.isnan(cols)
                    cols[hit] = data.time
                self.removed_volume += n_inside * grid.voxel_volume
                self._dirty = True
                if state is _IDLE:
                    state = CutState()
                state.cutting = True
            elif n_inside:
                # Uncut foam against a cutter that does not cut: a spring from where the
                # cutter first pressed in, along the direction into the material then (the
                # overlap's centroid seen from the axis), plus damping while pressing on.
                if self._block is None:
                    weights, *_, dx, dy, inside = self._overlap(cx, cy, z0, z1)  # (numpy: once per contact)
                    ii, jj, _ = np.nonzero(inside)
                    mx, my = float(dx[ii].mean()), float(dy[jj].mean())
                    norm = math.hypot(mx, my)
                    if norm < 1e-9:
                        mx, my, norm = vx, vy, max(speed, 1e-12)
                    thickness = max(float(weights.sum()), float(grid.h[2]))
                    pen0 = n_inside * grid.voxel_volume / (2 * r * thickness)  # equivalent flat-face penetration
                    self._block = (cx, cy, mx / norm, my / norm, pen0)
                bx, by, nx_, ny_, pen0 = self._block
                delta = max((cx - bx) * nx_ + (cy - by) * ny_ + pen0, 0.0)
                magnitude = foam.block_stiffness * delta + foam.block_damping * max(vx * nx_ + vy * ny_, 0.0)
                fx, fy = -magnitude * nx_, -magnitude * ny_
                state = CutState(force=np.array([fx, fy, 0.0]), feed_speed=speed, blocked=True)
            if not n_inside or cutting:
                self._block = None
        self._recent_i = (ri + 1) % len(recent)
        self._apply(fx, fy, cx, cy, z_mid, torque, omega, dt)
        self.state = state
        return state

    def _fuse(self, data: mujoco.MjData, kernels: dict[str, Any]) -> None:
        """Set up the fused step (``cutting_kernels._tick``): its constants and state in one
        float and one int array, the buffers it reads and writes by address (MuJoCo's live as
        long as ``data``; the others are this cutter's and are kept). The spindle loop's state
        becomes a view of its slots (``SpindleLoop.state``)."""
        functions = ck.mujoco_functions()
        if functions is None:
            return  # MuJoCo's library not found by path: the Python step (the same numbers)
        model, grid, foam, tools = self.model, self.grid, self.foam, self.tools
        fv = np.zeros(ck.N_F)
        fv[ck.F_SP_OPT:ck.F_SP_OPT + 6] = (tools.spindle_kv, tools.spindle_ki, tools.spindle_max_torque,
                                           tools.spindle_stall_fraction, tools.spindle_stall_time, tools.spindle_max_speed)
        fv[ck.F_SP:ck.F_SP + 4] = self.spindle.state
        self.spindle.state = fv[ck.F_SP:ck.F_SP + 4]
        fv[ck.F_VOXEL] = grid.voxel_volume
        fv[ck.F_ZMID], fv[ck.F_HALF], fv[ck.F_R], fv[ck.F_PROBE] = self._z_mid, self.half_length, self.radius, self._probe
        fv[ck.F_PROBE2], fv[ck.F_MIN_SPEED], fv[ck.F_U] = self._probe2, foam.min_cutting_speed, self.u
        fv[ck.F_RADIAL], fv[ck.F_INERTIA] = foam.radial_ratio, self.spindle_inertia
        fv[ck.F_BOX:ck.F_BOX + 6] = self._box
        self._applied_force = fv[ck.F_APPLIED:ck.F_APPLIED + 6]  # (a view: _apply and the kernel share it)
        self._consts = [np.ascontiguousarray(a, dtype=float) for a in (
            *grid.centres, self._edges, grid.lo, grid.h, self._cos_t, self._sin_t, self._i_cc, self._i_cs, self._i_c)]
        iv = np.zeros(ck.N_I, np.int64)
        jac, solve = functions
        iv[ck.I_BODY], iv[ck.I_NV], iv[ck.I_M], iv[ck.I_D] = self.body, model.nv, model._address, data._address
        iv[ck.I_JAC], iv[ck.I_SOLVE], iv[ck.I_NPROBE], iv[ck.I_TWO] = jac, solve, len(self._theta), 2
        views = (self._xpos_row, self._xmat_row, self._cvel_row, self._com_row, self._xipos_row, self._xfrc_row,
                 self._qfrc[self.spindle_dof:], self._qacc, self._jac, self._minv_jt, self._point, *self._consts,
                 self._qvel[self.spindle_dof:], self._ctrl[self.spindle_actuator:])
        for slot, view in enumerate(views, start=ck.I_XPOS):
            assert view.dtype == np.float64 and view.flags.c_contiguous, slot
            iv[slot] = view.ctypes.data
        self._fv, self._iv = fv, iv
        self._native_tick = kernels["tick"]  # (``_step`` inside it)

    def _overlap(self, cx: float, cy: float, z0: float, z1: float) -> tuple[Any, ...]:
        """numpy path: (layer weights, i0, i1, j0, j1, k0, k1, dx, dy, inside) with ``inside`` the
        material voxels of ``material[i0:i1, j0:j1, k0:k1]`` whose centres lie in the cutter."""
        grid, r = self.grid, self.radius
        weights = grid.layer_weights(z0, z1)
        i0, i1 = grid.index_range(0, cx - r, cx + r)
        j0, j1 = grid.index_range(1, cy - r, cy + r)
        k0, k1 = grid.index_range(2, z0, z1)
        dx = grid.centres[0][i0:i1] - cx
        dy = grid.centres[1][j0:j1] - cy
        inside_xy = dx[:, None] ** 2 + dy[None, :] ** 2 <= r * r
        zc = grid.centres[2][k0:k1]
        block = grid.material[i0:i1, j0:j1, k0:k1]
        inside = block & inside_xy[:, :, None] & ((zc >= z0) & (zc <= z1))[None, None, :]
        return weights, i0, i1, j0, j1, k0, k1, dx, dy, inside

    def _implicit_feed(self, vx: float, vy: float, ex: float, ey: float, a: float, b: float, dt: float,
                       x: float, y: float) -> float:
        """End-of-step feed speed along (ex, ey) under the cutting force −s·(a·e_f + b·e_n), ≥ 0."""
        model, data = self.model, self.data
        point = self._point
        point[0] = x
        point[1] = y
        mujoco.mj_jac(model, data, self._jac, None, point, self.body)
        jxy = self._jxy
        minv_jt = self._minv_jt
        mujoco.mj_solveM(model, data, minv_jt, jxy)
        # (np.dot: the same BLAS calls as ``@`` — gemm, gemv, dot — with less dispatch)
        inv_l = np.dot(jxy, minv_jt.T)  # 2×2 inverse inertia at the point
        acc = np.dot(jxy, self._qacc) - np.dot(inv_l, self._applied_force[:2])  # last step's, without the cutting force
        acc0, acc1 = acc.tolist()
        w = (vx + dt * acc0) * ex + (vy + dt * acc1) * ey
        # (preallocated vectors; the same BLAS products as with new arrays)
        e, g = self._e, self._g
        e[0] = ex
        e[1] = ey
        g[0] = a * ex - b * ey
        g[1] = a * ey + b * ex
        gain = float(np.dot(np.dot(e, inv_l), g))
        return max(w, 0.0) / (1.0 + dt * max(gain, 0.0))

    def _apply(self, fx: float, fy: float, x: float, y: float, z: float, torque: float, omega: float, dt: float) -> None:
        """Add the in-plane cutter force (at (x, y, z)) to the housing and the load torque to the spindle."""
        c0, c1, c2 = self._xipos_row.tolist()
        rx, ry, rz = x - c0, y - c1, z - c2
        wrench = self._wrench
        wrench[:] = (fx, fy, 0.0, -rz * fy, rz * fx, rx * fy - ry * fx)  # force; r × F
        np.subtract(wrench, self._applied_force, out=self._delta)
        self._xfrc_row += self._delta
        self._applied_force[:] = wrench
        # The load resists the spin but cannot reverse it within one step.
        load = -math.copysign(min(torque, self.spindle_inertia * abs(omega) / dt), omega) if torque > 0 else 0.0
        self._qfrc[self.spindle_dof] += load - self._applied_torque
        self._applied_torque = load

    def after_step(self) -> bool:
        """After ``mj_step`` (any cadence): check connectivity, release the sample. True if freed now."""
        fv = self._fv
        if fv is not None and fv[ck.F_DIRTY] != 0.0:  # (the fused step removed material)
            fv[ck.F_DIRTY] = 0.0
            self._dirty = True
        if self.detached or not self._dirty:
            return False
        if self.data.time - self._last_check < self.foam.connectivity_period:
            return False
        self._dirty = False
        self._last_check = float(self.data.time)
        return self.check_connectivity()

    def check_connectivity(self) -> bool:
        """Free the sample when the held material lost the clamp (face connectivity to i = 0).

        The numpy path labels the whole grid (``scipy.ndimage.label``); the native one floods
        from the held material towards the anchor face and stops there (a connected grid, the
        usual case, costs a short walk), and only on detachment floods from the anchor face to
        find what left. Both free the same voxels at the same check."""
        self.checks += 1
        material = self.grid.material
        if self._native is not None:
            if self._native["held_anchored"](material, self._held_flat) != 0:
                return False
            self.freed_volume = float(self._native["free_loose"](material)) * self.grid.voxel_volume
        else:
            labels, _ = ndimage.label(material)
            anchored = np.unique(labels[0])
            anchored = anchored[anchored > 0]
            held = labels[self._held_columns]
            held = held[held > 0]
            if held.size == 0 or np.isin(held, anchored).any():
                return False
            loose = (labels > 0) & ~np.isin(labels, anchored)
            self.freed_volume = float(np.count_nonzero(loose)) * self.grid.voxel_volume
            material[loose] = False
        self.data.eq_active[self.weld] = 0
        self.detach_time = float(self.data.time)
        self.model.geom_rgba[self._band, 3] = 0.0
        return True

    def status(self) -> dict[str, Any]:
        """A JSON-ready summary for run reports."""
        return {
            "detached": self.detached,
            "detach_time_s": self.detach_time,
            "removed_volume_m3": self.removed_volume,
            "freed_volume_m3": self.freed_volume,
            "spindle_events": [{"time_s": t, "event": e, "speed_rad_s": w} for t, e, w in self.spindle.events],
            "connectivity_checks": self.checks,
            "voxels": list(self.grid.shape),
            "voxel_size_m": [float(h) for h in self.grid.h],
        }


def _compiled_kernels() -> dict[str, Any]:
    """``cutting_kernels.kernels()``, each run once on a scratch grid so numba compiles (or
    loads its cache) here, with Ctrl-C held until done, not in the first cutting step."""
    from . import cutting_kernels
    from .jit import sigint_deferred

    with sigint_deferred():
        k = cutting_kernels.kernels()
        material = np.ones((2, 2, 2), dtype=bool)
        c = np.array([0.25, 0.75])
        lo, h = np.zeros(3), np.full(3, 0.5)
        edges, recent, trig = np.array([0.0, 0.5, 1.0]), np.full((2, 2), np.inf), np.array([0.6, 0.8])
        k["engage"](material, c, c, c, edges, lo, h, recent, trig, trig, trig, trig, trig,
                    0.5, 0.5, 0.0, 1.0, 0.4, 0.9, 0.8, 1.0, 0.0, True)
        k["remove"](material, np.zeros_like(material), np.full((2, 2), np.nan, np.float32), c, c, c, lo, h,
                    0.5, 0.5, 0.0, 1.0, 0.4, 0.0)
        k["held_anchored"](material, np.array([1], np.int64))
        k["free_loose"](material)
        k["columns_with_material"](material, np.array([1], np.int64))
        # The fused step (``_step`` inside ``_tick``), far from any material (an empty box): it only
        # writes the scratch buffers.
        fv, iv = np.zeros(ck.N_F), np.zeros(ck.N_I, np.int64)
        fv[ck.F_BOX:ck.F_BOX + 3], fv[ck.F_DT] = 1.0, 1.0
        scratch = np.zeros(32)
        iv[ck.I_XPOS:ck.I_CTRL + 1] = scratch.ctypes.data
        k["tick"](material, np.zeros_like(material), np.full((2, 2), np.nan, np.float32), recent, fv, iv,
                  np.zeros(ck.N_A), 0.0, 0.0, 1.0)
    return k


def _add(acc: np.ndarray, s: CutState, active: bool) -> None:
    """Add one step's CutState to the sums ``acc`` (``FoamCutter.tick``'s Python path; the
    fused kernel adds in the same order)."""
    if s is not _IDLE:  # (adding _IDLE's +0.0s leaves the sums as they are: they are never −0.0)
        acc[:10] += (*s.force, s.feed_force, s.normal_force, s.torque, s.power, s.mrr, s.depth, s.chip)
        if s.blocked:
            acc[ck.A_BLOCKED] = 1.0
        if active:
            acc[ck.A_ACTIVE] = 1.0
    acc[ck.A_STEPS] += 1.0


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise ValueError(f"model has no {kind.name.removeprefix('mjOBJ_').lower()} named {name!r}")
    return int(i)


def foam_cutter(model: mujoco.MjModel, data: mujoco.MjData, layout: Any, scene: Any, arm: str = "left") -> FoamCutter:
    """The ``FoamCutter`` of a scene built by ``scene.build_scene`` from ``layout`` and ``scene``.

    The grid covers the plate outside the clamped strip (the clamp side is the anchor);
    the held region is around the gripper's grasp point.
    """
    plate = layout.plate
    bottom = plate.top_z - plate.thickness
    x0 = plate.corner_x - plate.size[0] + layout.clamp_length
    lo = np.array([x0, plate.corner_y, bottom])
    hi = np.array([plate.corner_x, plate.corner_y + plate.size[1], plate.top_z])
    grid = FoamGrid(lo, hi, scene.foam.voxel_size)
    sample_lo = np.array([plate.corner_x - plate.sample_x, plate.corner_y])
    sample_hi = np.array([plate.corner_x, plate.corner_y + plate.sample_y])
    grasp = layout.grasp_pose()[:3, 3]
    return FoamCutter(model, data, grid, scene.foam, scene.tools, plate.density, grasp, (sample_lo, sample_hi), arm=arm,
                      kerf=(plate.kerf_polyline(), plate.kerf_width))


def kerf_profile(
    removed: np.ndarray, lo: np.ndarray, spacing: np.ndarray, polyline: np.ndarray, step: float, search: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kerf as cut, measured from a column map (``FoamGrid.cut_map() > 0.5``).

    At stations every ``step`` along each leg of the planned ``polyline`` (x, y), scan the
    map across the leg within ±``search``; the run of removed columns nearest the planned
    line gives the kerf's edges. Returns (stations (n, 2) on the plan, cut centres (n, 2),
    widths (n,)); NaN where nothing was cut there. Stations within ``search`` of an inner
    vertex are left out (there the scan line runs along the other leg's kerf). The cut
    centres are the "real toolpath" measured from the cut itself (the paper's Fig. 16b);
    their resolution is the voxel (a column is cut when its centre is inside the cutter).
    """
    removed = np.asarray(removed, bool)
    lo, spacing = np.asarray(lo, float)[:2], np.asarray(spacing, float)[:2]
    fine = float(min(spacing)) / 4
    offsets = np.arange(-search, search + fine / 2, fine)
    stations, centres, widths = [], [], []
    pts = np.asarray(polyline, float)[:, :2]
    for a, b in itertools.pairwise(pts):
        length = float(np.linalg.norm(b - a))
        if length <= 0:
            continue
        u = (b - a) / length
        n = np.array([-u[1], u[0]])
        for s in np.arange(step / 2, length, step):
            p = a + s * u
            if any(float(np.linalg.norm(p - v)) < search for v in pts[1:-1]):
                continue  # near an inner corner the scan would run along the other leg's kerf
            line = p[None, :] + offsets[:, None] * n[None, :]
            ij = np.floor((line - lo) / spacing).astype(int)
            ok = (ij[:, 0] >= 0) & (ij[:, 0] < removed.shape[0]) & (ij[:, 1] >= 0) & (ij[:, 1] < removed.shape[1])
            cut = np.zeros(len(offsets), bool)
            cut[ok] = removed[ij[ok, 0], ij[ok, 1]]
            stations.append(p)
            if not cut.any():
                centres.append(np.full(2, np.nan))
                widths.append(np.nan)
                continue
            # Runs of removed samples; the one whose centre lies nearest the planned line.
            edges = np.flatnonzero(np.diff(np.concatenate([[0], cut.astype(int), [0]])))
            runs = edges.reshape(-1, 2)
            mids = np.array([(offsets[r0] + offsets[r1 - 1]) / 2 for r0, r1 in runs])
            r0, r1 = runs[int(np.argmin(np.abs(mids)))]
            lo_off, hi_off = offsets[r0] - fine / 2, offsets[r1 - 1] + fine / 2
            centres.append(p + n * (lo_off + hi_off) / 2)
            widths.append(hi_off - lo_off)
    return np.array(stations).reshape(-1, 2), np.array(centres).reshape(-1, 2), np.array(widths)


# ------------------------------------------------------------------ run integration
RECORD_FIELDS = (
    "cut_force",  # (N, 3) mean force on the cutter over the tick before the record, N
    "cut_feed_force",  # (N,) against the feed, N
    "cut_normal_force",  # (N,) across the feed, N
    "cut_torque",  # (N,) cutting torque on the spindle, N·m
    "cut_power",  # (N,) W
    "cut_mrr",  # (N,) material removal rate, m³/s
    "cut_depth",  # (N,) mean engaged depth, m
    "cut_chip",  # (N,) feed per revolution, m
    "cut_active",  # (N,) the cutter removed material during the tick
    "cut_blocked",  # (N,) a non-cutting cutter was pressed into material
    "cut_removed_volume",  # (N,) cumulative, m³
    "cutter_pos",  # (N, 3) cutter centre, world
    "spindle_reference",  # (N,) commanded speed, rad/s
    "cut_spindle_speed",  # (N,) measured spindle speed, rad/s
    "spindle_stalled",  # (N,) the drive tripped on a stall
)

CUTTING_ARRAYS = (*RECORD_FIELDS, "kerf_map", "kerf_map_lo", "kerf_map_spacing", "spindle_stall_times")


@dataclass(frozen=True)
class CuttingRecord:
    """What the cutter did in one run: per-record series and the cut kerf (SI units).

    Saved into ``trajectory.npz`` by ``arrays()`` (keys as named, plus ``kerf_map``,
    ``kerf_map_lo``, ``kerf_map_spacing``, ``spindle_stall_times``) and restored by
    ``from_arrays``; ``cutting_metrics`` needs nothing else.
    """

    series: dict[str, np.ndarray]
    kerf_map: np.ndarray  # (nx, ny) fraction of each voxel column the cutter removed
    kerf_map_lo: np.ndarray  # (3,) grid corner (x, y, z), m
    kerf_map_spacing: np.ndarray  # (3,) voxel size, m
    spindle_stall_times: np.ndarray  # (events,) s

    def arrays(self) -> dict[str, np.ndarray]:
        return {**self.series, "kerf_map": self.kerf_map, "kerf_map_lo": self.kerf_map_lo,
                "kerf_map_spacing": self.kerf_map_spacing, "spindle_stall_times": self.spindle_stall_times}

    @classmethod
    def from_arrays(cls, data: dict[str, np.ndarray]) -> CuttingRecord:
        return cls({k: np.asarray(data[k]) for k in RECORD_FIELDS}, np.asarray(data["kerf_map"]),
                   np.asarray(data["kerf_map_lo"]), np.asarray(data["kerf_map_spacing"]),
                   np.asarray(data["spindle_stall_times"]))


class CuttingObserver:
    """The tick-loop hooks of ``scenario.simulate`` (duck-typed ``Observer``): the cutter's
    ``step`` before every physics step (spindle set-point from ``sim.commands``), the
    connectivity check after each tick, one record row every ``every`` ticks."""

    def __init__(self, sim: Any, layout: Any, scene: Any, every: int = 1) -> None:
        arm = sim.handles.tool_arm["grinder"] if hasattr(sim.handles, "tool_arm") else "left"
        self.cutter = foam_cutter(sim.model, sim.data, layout, scene, arm=arm)
        self.every = max(1, int(every))
        self.rows: dict[str, list[Any]] = {k: [] for k in RECORD_FIELDS}
        self._row_lists = [self.rows[k] for k in RECORD_FIELDS]
        # The sums over the tick's steps (``cutting_kernels.N_A`` slots: the CutState's force
        # and scalars, "removed something", "blocked", steps), added to by ``FoamCutter.tick``.
        self._acc = np.zeros(ck.N_A)
        self._reference = 0.0

    def start(self, sim: Any) -> None:
        """Nothing to prepare: the cutter was built uncut."""

    def before_tick(self, sim: Any) -> None:
        acc = self._acc
        if sim.tick % self.every == 0:
            n = max(int(acc[ck.A_STEPS]), 1)
            mean = acc[:10] / n
            c = self.cutter
            # In RECORD_FIELDS order; scalars as they are (``record`` stacks them), the one
            # array that aliases MuJoCo's state copied (``mean`` is new every tick).
            values = (
                mean[0:3], mean[3], mean[4], mean[5], mean[6], mean[7], mean[8], mean[9], acc[ck.A_ACTIVE] != 0.0,
                acc[ck.A_BLOCKED] != 0.0,
                c.removed_volume, c._xpos_row.copy(), self._reference, c.spindle_speed, c.stalled,
            )
            for rows, value in zip(self._row_lists, values, strict=True):
                rows.append(value)
        acc[:] = 0.0

    def before_physics_step(self, sim: Any) -> None:
        commands = getattr(sim, "commands", None)
        self._reference = reference = float(getattr(commands, "spindle_speed", 0.0) or 0.0)
        self.cutter.tick(reference, self._acc)

    def after_physics_step(self, sim: Any) -> None:
        """Nothing per step after MuJoCo's: removal happens before it."""

    def after_tick(self, _sim: Any) -> str | None:
        self.cutter.after_step()
        return None

    def close(self, sim: Any) -> None:
        """Nothing to release."""

    def record(self) -> CuttingRecord:
        """The run's ``CuttingRecord`` (call after the run)."""
        g = self.cutter.grid
        # np.array, not np.stack: the same arrays (dtype, shape, values: tests/test_metrics_fast.py),
        # without stack's one asanyarray per row (24 ms of a default run's 3209 rows × 15 fields).
        series = {k: np.array(v) if v else np.zeros((0,)) for k, v in self.rows.items()}
        stalls = np.array([t for t, e, _ in self.cutter.spindle.events if e == "stall"], dtype=float)
        return CuttingRecord(series, g.cut_map().astype(np.float32), g.lo.copy(), g.h.copy(), stalls)


def cutting_metrics(record: CuttingRecord, kerf_polyline: np.ndarray, kerf_width: float) -> dict[str, Any]:
    """Cutting force, spindle, stall, removal and the kerf as cut (a pure function of the record).

    ``kerf_polyline`` is the planned cut centre line (layout); the kerf is measured from the
    cut itself (``kerf_profile`` on ``kerf_map``): its centre's deviation from the plan and
    its width.
    """
    s = record.series
    active = s["cut_active"].astype(bool)
    force = np.linalg.norm(s["cut_force"][:, :2], axis=1) if len(active) else np.zeros(0)

    def stats(x: np.ndarray) -> dict[str, float | None]:
        return {"mean": float(x.mean()) if x.size else None, "max": float(x.max()) if x.size else None}

    out: dict[str, Any] = {
        "force_n": stats(force[active]),
        "feed_force_n": stats(s["cut_feed_force"][active]),
        "normal_force_n": stats(np.abs(s["cut_normal_force"][active])),
        "torque_nm": stats(s["cut_torque"][active]),
        "power_w": stats(s["cut_power"][active]),
        "removed_volume_m3": float(s["cut_removed_volume"][-1]) if len(active) else 0.0,
        "stall_events": len(record.spindle_stall_times),
        "stall_times_s": [float(t) for t in record.spindle_stall_times],
        "blocked": bool(s["cut_blocked"].any()) if len(active) else False,
    }
    speed = s["cut_spindle_speed"]
    if active.any():
        ref = s["spindle_reference"][active]
        out["spindle_speed_drop_pct"] = {
            "mean": float(np.mean((ref - speed[active]) / ref) * 100), "max": float(np.max((ref - speed[active]) / ref) * 100)}
    else:
        out["spindle_speed_drop_pct"] = {"mean": None, "max": None}
    lo, h = record.kerf_map_lo, record.kerf_map_spacing
    stations, centres, widths = kerf_profile(record.kerf_map > 0.5, lo, h, np.asarray(kerf_polyline)[:, :2],
                                             step=float(h[:2].min()), search=1.5 * kerf_width)
    cut = ~np.isnan(widths)
    dev = np.linalg.norm(centres[cut] - stations[cut], axis=1) * 1000 if cut.any() else np.zeros(0)
    out["kerf"] = {
        "coverage": float(cut.mean()) if cut.size else 0.0,  # fraction of the planned kerf where a cut was found
        "width_mm": {"mean": float(widths[cut].mean() * 1000) if cut.any() else None,
                     "min": float(widths[cut].min() * 1000) if cut.any() else None},
        "centre_deviation_mm": {"mean": float(dev.mean()) if dev.size else None, "max": float(dev.max()) if dev.size else None},
    }
    return out


def write_cutting_plots(record: CuttingRecord, t: np.ndarray, kerf_polyline: np.ndarray, kerf_width: float,
                        out_dir: Any) -> list[Any]:
    """``cut_kerf.png`` (the kerf as cut from above, its measured centre line against the
    plan: the paper's Fig. 16b from the cut itself) and ``cut_force.png`` (force, torque,
    spindle speed over time, stalls marked)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..configio import atomic_write_figure

    paths = []
    lo, h = record.kerf_map_lo, record.kerf_map_spacing
    _, centres, widths = kerf_profile(record.kerf_map > 0.5, lo, h, np.asarray(kerf_polyline)[:, :2],
                                             step=float(h[:2].min()), search=1.5 * kerf_width)
    fig, ax = plt.subplots(figsize=(6, 5))
    nx, ny = record.kerf_map.shape
    extent = (lo[0] * 1e3, (lo[0] + nx * h[0]) * 1e3, lo[1] * 1e3, (lo[1] + ny * h[1]) * 1e3)
    image = ax.imshow(record.kerf_map.T, origin="lower", extent=extent, cmap="Oranges", vmin=0, vmax=1, interpolation="nearest")
    fig.colorbar(image, ax=ax, shrink=0.8, label="removed fraction of the voxel column")
    line = np.asarray(kerf_polyline)[:, :2] * 1e3
    ax.plot(line[:, 0], line[:, 1], "b--", lw=1, label="planned kerf centre")
    ok = ~np.isnan(widths)
    ax.plot(centres[ok, 0] * 1e3, centres[ok, 1] * 1e3, "k.", ms=2, label="kerf centre measured from the cut")
    pad = 1.5 * kerf_width * 1e3
    ax.set_xlim(line[:, 0].min() - pad, line[:, 0].max() + pad)
    ax.set_ylim(line[:, 1].min() - pad, line[:, 1].max() + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title("the cut from above")
    ax.legend(loc="lower left", fontsize=7)
    paths.append(atomic_write_figure(fig, Path(out_dir) / "cut_kerf.png"))

    s = record.series
    fig, axes = plt.subplots(3, 1, figsize=(8, 6), sharex=True)
    axes[0].plot(t, np.linalg.norm(s["cut_force"][:, :2], axis=1), label="|F| in plane")
    axes[0].plot(t, s["cut_feed_force"], label="against feed")
    axes[0].plot(t, np.abs(s["cut_normal_force"]), label="|across feed|")
    axes[0].set_ylabel("cutting force (N)")
    axes[0].legend(fontsize=7)
    axes[1].plot(t, s["cut_torque"] * 1e3)
    axes[1].set_ylabel("torque (mN·m)")
    axes[2].plot(t, s["cut_spindle_speed"], label="speed")
    axes[2].plot(t, s["spindle_reference"], "--", label="command")
    for ts in record.spindle_stall_times:
        for a in axes:
            a.axvline(ts, color="r", lw=1)
    axes[2].set_ylabel("spindle (rad/s)")
    axes[2].set_xlabel("time (s)")
    axes[2].legend(fontsize=7)
    paths.append(atomic_write_figure(fig, Path(out_dir) / "cut_force.png"))
    return paths
