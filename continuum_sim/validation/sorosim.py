"""SoRoSim Cosserat-rod static shapes (``validation/sorosim``) and the model's answer to them.

Layout of a statics CSV (see the data's README): a label row, an arc-length row
(normalised position of 7 Gauss–Lobatto stations in each half of the rod), then 6 rows
per load case, ``EulX, EulY, EulZ, Px, Py, Pz``. Columns ``gravity`` (m/s², P rows),
``mid_wrench`` (s = L/2) and ``tip_wrench`` (s = L) hold the moment (N·m) in the Eul rows
and the force (N) in the P rows, in the fixed file frame; station columns hold the
centreline's Euler angles and position. The rod is clamped at the origin along +x.

The Euler convention is not documented; the data fit intrinsic X-Y-Z rotations
(``EULER_SEQUENCE``, scipy notation) whose first axis is the centreline tangent, and no
other sequence does (checked by a test against the stations' positions).
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..configio import ConfigError
from ..model.rod import RodJoint, RodSpec, apply_node_wrench, centreline, compile_rod, node_body_ids, node_poses
from .statics import StaticSolver, StaticSolverOptions

Array = NDArray[np.float64]

DATA_ENV = "CONTINUUM_SIM_SOROSIM"
EULER_SEQUENCE = "XYZ"
MID_STATION = 6  # seg1_s07, s = L/2 (the tip is the last station)


@dataclass(frozen=True)
class SorosimRod:
    """One reference rod: its material and section (data README) and its statics file."""

    name: str
    statics_file: str
    length: float
    radius: float
    youngs_modulus: float
    poisson_ratio: float
    density: float

    def spec(self, n_links: int, joint: RodJoint = "ball_twist") -> RodSpec:
        return RodSpec(self.length, self.radius, self.youngs_modulus, self.poisson_ratio, self.density, n_links, joint)


STEEL = SorosimRod("steel", "SpringSteelRodMuJoCo_dataStatics.csv", 0.6, 0.8e-3, 200e9, 0.33, 7870.0)
TPU = SorosimRod("tpu", "TPURodMuJoCo_dataStatics.csv", 0.4, 5e-3, 70e6, 0.4, 1200.0)
RODS = {rod.name: rod for rod in (STEEL, TPU)}


@dataclass(frozen=True)
class StaticCase:
    """One load case and the reference centreline at its stations."""

    index: int
    gravity: Array  # (3,) m/s²
    mid_wrench: Array  # (6,) force N, moment N·m (MuJoCo's xfrc order), at s = L/2
    tip_wrench: Array  # (6,) at s = L
    arclength: Array  # (14,) m
    positions: Array  # (14, 3) m
    euler: Array  # (14, 3) rad, EULER_SEQUENCE

    def rotations(self) -> Array:
        """(14, 3, 3) cross-section frames at the stations (tangent = first column)."""
        from scipy.spatial.transform import Rotation

        return Rotation.from_euler(EULER_SEQUENCE, self.euler).as_matrix()


def data_dir() -> Path:
    """``$CONTINUUM_SIM_SOROSIM`` if set, else the repository's ``validation/sorosim``."""
    env = os.environ.get(DATA_ENV)
    return Path(env) if env else Path(__file__).resolve().parents[2] / "validation" / "sorosim"


def load_statics(rod: SorosimRod, directory: Path | None = None) -> list[StaticCase]:
    """All load cases of ``rod``'s statics file, in file order."""
    path = (directory or data_dir()) / "sorosim_statics" / rod.statics_file
    if not path.is_file():
        raise ConfigError(DATA_ENV, f"SoRoSim statics file not found: {path}")
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    header, arc_row, body = rows[0], rows[1], rows[2:]
    if header[:4] != ["rowLabel", "gravity", "mid_wrench", "tip_wrench"] or len(body) % 6:
        raise ValueError(f"{path}: unexpected layout (header {header[:4]}, {len(body)} data rows)")
    half = np.array([float(v) for v in arc_row[4:]])
    n_station = len(half) // 2
    arclength = rod.length / 2.0 * np.concatenate([half[:n_station], 1.0 + half[n_station:]])
    expected = ["EulX", "EulY", "EulZ", "Px", "Py", "Pz"]
    cases = []
    for k in range(len(body) // 6):
        block = body[6 * k : 6 * k + 6]
        labels = [row[0].split("_")[0] for row in block]
        if labels != expected:
            raise ValueError(f"{path}: case {k + 1} rows are {labels}, expected {expected}")
        values = np.array([[float(v) for v in row[1:]] for row in block])  # (6, 3 + stations)
        eul, pos = values[:3], values[3:]

        def wrench(col: int, pos: Array = pos, eul: Array = eul) -> Array:  # this iteration's rows
            return np.concatenate([pos[:, col], eul[:, col]])  # force from P rows, moment from Eul rows

        cases.append(
            StaticCase(
                index=k,
                gravity=pos[:, 0].copy(),
                mid_wrench=wrench(1),
                tip_wrench=wrench(2),
                arclength=arclength,
                positions=pos[:, 3:].T.copy(),
                euler=eul[:, 3:].T.copy(),
            )
        )
    return cases


@dataclass(frozen=True)
class CaseError:
    """Model-minus-reference distances of one case (m)."""

    tip: float
    mid: float
    shape: float  # largest over the 14 stations
    tip_angle: float  # rad, rotation between model and reference tip cross-sections
    converged: bool
    evaluations: int


class RodStatics:
    """A compiled rod that solves SoRoSim load cases one after another."""

    def __init__(self, spec: RodSpec, options: StaticSolverOptions | None = None) -> None:
        import mujoco

        if spec.n_links % 2:
            raise ConfigError("n_links", f"must be even so that a node sits at s = L/2 (got {spec.n_links})")
        self.spec = spec
        self.model = compile_rod(spec)
        self.data = mujoco.MjData(self.model)
        self.solver = StaticSolver(self.model, self.data, options)
        self.nodes = node_body_ids(self.model, spec.n_links)

    def solve(self, case: StaticCase) -> tuple[Array, Array, bool, int]:
        """Node positions and rotations at equilibrium under ``case``'s loads, from straight."""
        m, d = self.model, self.data
        d.qpos[:] = m.qpos0
        d.xfrc_applied[:] = 0.0
        apply_node_wrench(m, d, self.nodes[self.spec.n_links // 2], case.mid_wrench[:3], case.mid_wrench[3:])
        apply_node_wrench(m, d, self.nodes[-1], case.tip_wrench[:3], case.tip_wrench[3:])
        result = self.solver.solve(case.gravity, d.xfrc_applied.copy())
        positions, rotations = node_poses(d, self.nodes)
        return positions, rotations, result.converged, result.evaluations

    def error(self, case: StaticCase) -> CaseError:
        positions, rotations, converged, evaluations = self.solve(case)
        model_stations = centreline(self.spec, positions, rotations, case.arclength)
        distance = np.linalg.norm(model_stations - case.positions, axis=1)
        relative = rotations[-1].T @ case.rotations()[-1]
        angle = float(np.arccos(np.clip((np.trace(relative) - 1.0) / 2.0, -1.0, 1.0)))
        return CaseError(
            float(distance[-1]), float(distance[MID_STATION]), float(distance.max()), angle, converged, evaluations
        )


def subset(cases: list[StaticCase], count: int, seed: int = 0) -> list[StaticCase]:
    """``count`` cases drawn without replacement by a seeded generator (all when count ≥ len)."""
    if count >= len(cases):
        return list(cases)
    picks = np.random.default_rng(seed).choice(len(cases), size=count, replace=False)
    return [cases[i] for i in sorted(picks)]


def summarise(rod: SorosimRod, spec: RodSpec, errors: list[CaseError], seconds: float) -> dict:
    """One table row: errors in % of the rod length and degrees, cost per case."""
    tip = 100.0 * np.array([e.tip for e in errors]) / rod.length
    mid = 100.0 * np.array([e.mid for e in errors]) / rod.length
    shape = 100.0 * np.array([e.shape for e in errors]) / rod.length
    angle = np.degrees([e.tip_angle for e in errors])
    return {
        "rod": rod.name,
        "joint": spec.joint,
        "n_links": spec.n_links,
        "cases": len(errors),
        "tip_mean_pct": float(tip.mean()),
        "tip_max_pct": float(tip.max()),
        "mid_mean_pct": float(mid.mean()),
        "shape_max_pct": float(shape.max()),
        "tip_angle_mean_deg": float(angle.mean()),
        "tip_angle_max_deg": float(angle.max()),
        "converged": int(sum(e.converged for e in errors)),
        "ms_per_case": 1000.0 * seconds / len(errors),
    }


def markdown_table(rows: list[dict]) -> str:
    """The rows of ``summarise`` as a Markdown table."""
    head = (
        "| rod | joint | links | cases | tip mean % L | tip max % L | mid mean % L | worst station % L "
        "| tip angle mean ° | tip angle max ° | converged | ms/case |\n"
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n"
    )
    body = "".join(
        f"| {r['rod']} | {r['joint']} | {r['n_links']} | {r['cases']} | {r['tip_mean_pct']:.3f} | "
        f"{r['tip_max_pct']:.3f} | {r['mid_mean_pct']:.3f} | {r['shape_max_pct']:.3f} | "
        f"{r['tip_angle_mean_deg']:.2f} | {r['tip_angle_max_deg']:.2f} | {r['converged']}/{r['cases']} | "
        f"{r['ms_per_case']:.1f} |\n"
        for r in rows
    )
    return head + body
