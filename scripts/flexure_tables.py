"""Write the default arm's leaf tables into continuum_sim/data/flexure/ (the shipped cache of plant.flexure).

    PYTHONPATH=$PWD python scripts/flexure_tables.py

Run after changing the default leaf geometry, the solver or the grid (TABLE_VERSION);
tests/test_flexure_nonlinear.py checks a shipped table against a fresh solve.
"""

from __future__ import annotations

import math

import numpy as np

from continuum_sim.geometry import ArmGeometry
from continuum_sim.plant import flexure
from continuum_sim.plant.leaf_rod import SHIPPED, leaf_table, section_segment, table_name


def main() -> None:
    SHIPPED.mkdir(parents=True, exist_ok=True)
    geometry = ArmGeometry()
    n_psi = int(round(180.0 / flexure.PHI_STEP_DEG)) + 1
    n_theta = int(round(flexure.THETA_MAX_DEG / flexure.THETA_STEP_DEG)) + 1
    keep = set()
    for k, section in enumerate(geometry.sections):
        segment = section_segment(geometry, section)
        _, _, table = leaf_table(segment, math.radians(flexure.THETA_MAX_DEG), n_theta, n_psi)
        name = table_name(segment, math.radians(flexure.THETA_MAX_DEG), n_theta, n_psi)
        np.savez(SHIPPED / name, table=table)
        keep.add(name)
        print(f"section {k}: {SHIPPED / name}")
    for old in SHIPPED.glob("*.npz"):
        if old.name not in keep:
            old.unlink()
            print(f"removed stale {old}")


if __name__ == "__main__":
    main()
