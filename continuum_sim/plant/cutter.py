"""The foam cutter: engagement, a material-removal cutting force, removal, detachment.

* **Engagement.** The cutter is a cylinder of radius R (``<arm>/grinder/cutter``, axis ≈
  the plate normal). Its feed velocity v_f is the housing's velocity at the cutter centre
  in the plate plane. On the leading half circle it samples the remaining material depth
  a(θ) (voxel columns, overlap with the cutter's axial extent) at ``engagement_points``
  angles θ from the feed direction, one voxel beyond the edge; a probe point a recent
  cutter centre reached before (the cutter jittered back and forth) has no chip — finer
  than the voxels can tell.
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
  gives |F_normal| = (π/4)·F_t and |F_feed| = (π/4)·(K_r/K_t)·F_t. The force is a stiff
  damper on a light tool, so the feed speed is taken at the end of the step (backward
  Euler with the cutter point's inverse inertia J M⁻¹ Jᵀ; the foam only resists).
* **Removal.** Voxels whose centres lie inside the cutter are removed while the spindle
  turns at least ``min_cutting_speed`` and is not stalled.
* **A cutter that does not cut** (spindle off or stalled) is pushed out of the remaining
  material by a spring-damper on the equivalent flat-face penetration (``block_*``).
* **Spindle.** The spindle drive (``spindle.SpindleDrive``) alone sets the spindle's
  actuator; the cutter reads whether it is stalled and loads the spindle joint with the
  cutting torque (``qfrc_applied``), so it slows under load.
* **Detachment.** Every ``connectivity_period`` after material was removed, the grid's
  face connectivity is checked (``foam.held_anchored``); the sample comes free when the
  material under the gripper's jaws (voxels within ``grip_radius`` of the grasp point) no
  longer connects to the clamped edge. Then the weld ``sample_weld`` is released and every
  voxel that lost its connection leaves the grid (it went with the sample).

Each step runs compiled (``cutter_kernels``: the only implementation). The forces are
added to ``xfrc_applied``/``qfrc_applied`` (what was added the step before is taken back
first), so other per-step models may add theirs.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from ..model.scene_options import FoamOptions
from ..model.tools import CUTTER_GEOM, GRINDER
from . import cutter_kernels as ck
from . import foam
from .foam import FoamGrid
from .jit import sigint_deferred
from .mujoco_native import mujoco_functions
from .spindle import SpindleDrive


@dataclass
class CutState:
    """What the cutter did in the last step (SI units)."""

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


class FoamCutter:
    """Voxel foam + cutting force + connectivity detachment (see module doc)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        grid: FoamGrid,
        options: FoamOptions,
        spindle: SpindleDrive,
        density: float,
        grasp_point: np.ndarray,
        sample_box: tuple[np.ndarray, np.ndarray],
        arm: str = "left",
        kerf: tuple[np.ndarray, float] | None = None,
    ) -> None:
        """``kerf`` (planned centre polyline, width) defines the kerf band the ``cells_*``
        views count (the planned cut, for progress reports); the material is the whole grid."""
        from ..model.scene import KERF_BAND, SAMPLE_BODY, SAMPLE_WELD

        self.model, self.data, self.grid, self.foam, self.spindle = model, data, grid, options, spindle
        self.u = options.cutting_energy(density)
        self.cutter = _id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{arm}/{GRINDER}/{CUTTER_GEOM}")
        self.body = int(model.geom_bodyid[self.cutter])
        self.spindle_dof = spindle.dof
        self.weld = _id(model, mujoco.mjtObj.mjOBJ_EQUALITY, SAMPLE_WELD)
        self.sample_body = _id(model, mujoco.mjtObj.mjOBJ_BODY, SAMPLE_BODY)
        band = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in KERF_BAND]
        self._band = np.array([g for g in band if g >= 0], dtype=int)
        self._band_alpha = model.geom_rgba[self._band, 3].copy()
        self.radius = float(model.geom_size[self.cutter, 0])
        self.half_length = float(model.geom_size[self.cutter, 1])
        dof = self.spindle_dof
        self.spindle_inertia = float(model.dof_armature[dof] + model.body_inertia[model.dof_bodyid[dof], 2])
        edges = np.linspace(-math.pi / 2, math.pi / 2, options.engagement_points + 1)
        theta = 0.5 * (edges[1:] + edges[:-1])
        a, b = edges[:-1], edges[1:]
        self._probes = np.ascontiguousarray(np.stack([
            np.cos(theta), np.sin(theta),
            (b - a) / 2 + (np.sin(2 * b) - np.sin(2 * a)) / 4,  # ∫cos² θ
            (np.sin(b) ** 2 - np.sin(a) ** 2) / 2,  # ∫cos θ sin θ
            np.sin(b) - np.sin(a),  # ∫cos θ
        ]))
        # Recent cutter centres: older history is the voxels'.
        self._recent = np.full((max(2, math.ceil(options.recent_window / float(model.opt.timestep))), 2), np.inf)
        self._held_flat, self._band_columns = _columns(grid, options, grasp_point, sample_box, kerf)
        self._band_flat = np.flatnonzero(self._band_columns).astype(np.int64)
        self.record = np.zeros(1, ck.CUTTER)
        s = self.record[0]
        s["lo"], s["h"], s["hi"], s["shape"] = grid.lo, grid.h, grid.hi, grid.shape
        # Sample one voxel beyond the edge: the voxel holding the point then has its centre
        # outside the cutter now and ahead of it, so it was never swept before.
        probe = self.radius + float(np.max(grid.h[:2]))
        for name, value in (("z_mid", 0.5 * float(grid.lo[2] + grid.hi[2])), ("half", self.half_length),
                            ("radius", self.radius), ("probe", probe), ("probe2", (probe - 1e-9) ** 2),
                            ("min_speed", options.min_cutting_speed), ("u", self.u), ("radial", options.radial_ratio),
                            ("inertia", self.spindle_inertia), ("voxel", grid.voxel_volume),
                            ("block_stiffness", options.block_stiffness), ("block_damping", options.block_damping)):
            s[name] = value
        self.sums = np.zeros(1, ck.SUMS)  # ``step``'s (nobody reads them)
        # The work arrays the kernels fill (mj_jac, mj_solveM) and the addresses they use;
        # MuJoCo's buffers live as long as ``data``, these as long as the cutter.
        self._jac, self._minv, self._point = np.zeros((3, model.nv)), np.zeros((2, model.nv)), np.zeros(3)
        self.pointers = np.zeros(1, ck.POINTERS)
        functions = mujoco_functions()
        self.native = functions is not None  # False: MuJoCo's public API between the two kernels
        p = self.pointers[0]
        if functions is not None:
            p["jac_fn"], p["solve_fn"] = functions
        p["model"], p["data"], p["body"], p["nv"] = model._address, data._address, self.body, model.nv
        root = int(model.body_rootid[self.body])
        for name, view in (("xpos", data.geom_xpos[self.cutter]), ("xmat", data.geom_xmat[self.cutter]),
                           ("cvel", data.cvel[self.body]), ("com", data.subtree_com[root]),
                           ("xipos", data.xipos[self.body]), ("xfrc", data.xfrc_applied[self.body]),
                           ("qfrc", data.qfrc_applied[dof:]), ("qacc", data.qacc), ("qvel", data.qvel[dof:]),
                           ("jac", self._jac), ("minv", self._minv), ("point", self._point)):
            assert view.dtype == np.float64 and view.flags.c_contiguous, name
            p[name] = view.ctypes.data
        self._opt, self._spindle_record = model.opt, spindle.record
        self._warm_up()
        self.reset()

    def _warm_up(self) -> None:
        """Compile the kernels (or load numba's cache) now, Ctrl-C held until done, not in the
        first cutting step: one step far from any material (an empty box) on scratch buffers."""
        with sigint_deferred():
            state = self.record.copy()
            state["lo"], state["hi"] = 1e9, 1e9
            pointers = self.pointers.copy()
            scratch = np.zeros(64)
            for name in ("xpos", "xmat", "cvel", "com", "xipos", "xfrc", "qfrc", "qvel"):
                pointers[name] = scratch.ctypes.data
            material = np.ones((2, 2, 2), bool)
            sums = np.zeros(1, ck.SUMS)
            args = (material, np.zeros_like(material), np.full((2, 2), np.nan, np.float32), self._recent.copy(),
                    self._probes, state, pointers, sums, self.spindle.record, 0.0, 1.0)
            if self.native:
                ck.tick(*args)
            else:
                ck.begin(args[3], state, pointers, self.spindle.record)
                ck.finish(*args[:8], 0.0, 1.0)
            foam.held_anchored(material, np.array([1], np.int64))
            foam.free_loose(material)
            foam.columns_with_material(material, np.array([1], np.int64))

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Uncut plate, welded sample (the MuJoCo state and the spindle are the caller's)."""
        self.grid.reset()
        self.model.geom_rgba[self._band, 3] = self._band_alpha
        self.data.eq_active[self.weld] = 1
        s = self.record[0]
        for name in ("applied", "torque_applied", "removed", "dirty", "block", "recent_i", "force", "feed_force",
                     "normal_force", "torque", "mrr", "power", "depth", "chip", "feed_speed", "cutting", "blocked"):
            s[name] = 0
        self._recent[:] = np.inf
        self.detach_time: float | None = None
        self.freed_volume = 0.0  # material that left with the sample
        self._last_check = -math.inf
        self.checks = 0

    @property
    def detached(self) -> bool:
        return self.detach_time is not None

    @property
    def removed_volume(self) -> float:
        """Material the cutter removed (m³)."""
        return float(self.record["removed"][0])

    @property
    def state(self) -> CutState:
        """What the cutter did in the last step."""
        s = self.record[0]
        fx, fy = s["force"].tolist()
        return CutState(force=np.array([fx, fy, 0.0]), feed_force=float(s["feed_force"]),
                        normal_force=float(s["normal_force"]), torque=float(s["torque"]), mrr=float(s["mrr"]),
                        power=float(s["power"]), depth=float(s["depth"]), chip=float(s["chip"]),
                        feed_speed=float(s["feed_speed"]), cutting=bool(s["cutting"]), blocked=bool(s["blocked"]))

    # Progress views over the planned kerf band's voxel columns (what the kerf cells were).
    @property
    def n_cells(self) -> int:
        """Voxel columns of the planned kerf's core (the middle half of its width)."""
        return int(np.count_nonzero(self._band_columns))

    @property
    def cells_remaining(self) -> int:
        """Kerf-band columns with material left in them."""
        return int(foam.columns_with_material(self.grid.material, self._band_flat))

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
    def tick(self, sums: np.ndarray) -> None:
        """Before one ``mj_step`` (after the spindle drive's): cutting force and torque, removal,
        the step's outputs added to ``sums`` (a ``cutter_kernels.SUMS`` record)."""
        grid, data = self.grid, self.data
        if self.native:
            ck.tick(grid.material, grid.cut, grid.removed_at, self._recent, self._probes, self.record, self.pointers,
                    sums, self._spindle_record, data.time, self._opt.timestep)
            return
        if ck.begin(self._recent, self.record, self.pointers, self.spindle.record):
            model, point = self.model, self._point
            point[:] = self.record["cx"][0], self.record["cy"][0], self.record["z_mid"][0]
            mujoco.mj_jac(model, data, self._jac, None, point, self.body)
            mujoco.mj_solveM(model, data, self._minv, self._jac[:2])
        ck.finish(grid.material, grid.cut, grid.removed_at, self._recent, self._probes, self.record, self.pointers,
                  sums, data.time, self._opt.timestep)

    def step(self) -> CutState:
        """``tick`` on scratch sums; the step's ``CutState``."""
        self.tick(self.sums)
        return self.state

    def after_step(self) -> bool:
        """After ``mj_step`` (any cadence): check connectivity, release the sample. True if freed now."""
        s = self.record[0]
        if self.detached or not s["dirty"]:
            return False
        if self.data.time - self._last_check < self.foam.connectivity_period:
            return False
        s["dirty"] = 0
        self._last_check = float(self.data.time)
        return self.check_connectivity()

    def check_connectivity(self) -> bool:
        """Free the sample when the held material lost the clamp (face connectivity to i = 0)."""
        self.checks += 1
        material = self.grid.material
        if foam.held_anchored(material, self._held_flat) != 0:
            return False
        self.freed_volume = float(foam.free_loose(material)) * self.grid.voxel_volume
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


def _columns(grid: FoamGrid, options: FoamOptions, grasp_point: np.ndarray, sample_box: tuple[np.ndarray, np.ndarray],
             kerf: tuple[np.ndarray, float] | None) -> tuple[np.ndarray, np.ndarray]:
    """(the held columns as flat (i, j) indices, the kerf band's columns as a mask).

    Held: the sample's columns within ``grip_radius`` of the grasp point (all of the sample's
    if none is). The band: the kerf's core, the middle half of its width, so a cut up to a
    quarter kerf width off the plan still clears every "cell"."""
    gx, gy = np.meshgrid(grid.centres[0], grid.centres[1], indexing="ij")
    lo, hi = sample_box
    in_sample = (gx >= lo[0]) & (gx <= hi[0]) & (gy >= lo[1]) & (gy <= hi[1])
    near = (gx - grasp_point[0]) ** 2 + (gy - grasp_point[1]) ** 2 <= options.grip_radius**2
    held = in_sample & near if (in_sample & near).any() else in_sample
    band = np.zeros(grid.shape[:2], dtype=bool)
    if kerf is not None:
        line, width = np.asarray(kerf[0], float)[:, :2], 0.5 * float(kerf[1])
        for a, b in itertools.pairwise(line):
            ab = b - a
            t = np.clip(((gx - a[0]) * ab[0] + (gy - a[1]) * ab[1]) / float(ab @ ab), 0.0, 1.0)
            band |= (gx - a[0] - t * ab[0]) ** 2 + (gy - a[1] - t * ab[1]) ** 2 <= (width / 2) ** 2
    return np.flatnonzero(held).astype(np.int64), band


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise ValueError(f"model has no {kind.name.removeprefix('mjOBJ_').lower()} named {name!r}")
    return int(i)


def foam_cutter(model: mujoco.MjModel, data: mujoco.MjData, layout: Any, scene: Any, spindle: SpindleDrive | None = None,
                arm: str = "left") -> FoamCutter:
    """The ``FoamCutter`` of a scene built by ``scene.build_scene`` from ``layout`` and ``scene``
    (``spindle``: the run's spindle drive; a new one if None). The grid covers the plate
    outside the clamped strip; the held region is around the gripper's grasp point."""
    plate = layout.plate
    grid = foam.plate_grid(layout, scene.foam.voxel_size)
    sample_lo = np.array([plate.corner_x - plate.sample_x, plate.corner_y])
    sample_hi = np.array([plate.corner_x, plate.corner_y + plate.sample_y])
    spindle = SpindleDrive(model, scene.tools, arm) if spindle is None else spindle
    return FoamCutter(model, data, grid, scene.foam, spindle, plate.density, layout.grasp_pose()[:3, 3],
                      (sample_lo, sample_hi), arm=arm, kerf=(plate.kerf_polyline(), plate.kerf_width))
