"""What the twist DoF does to an arm held open loop under gravity: hinge_pair (universal joint) vs hinge_triple (ball joint).

The gravity_sag evaluation (grinder payload, 3 s settles) in a planar and a spatial
pose, leaves on the axis and the strain-limited ones (the default). Prints a Markdown table for docs/model.md;
``--out`` also writes it to a file:

    python scripts/twist_compliance.py [--out docs/model/twist_compliance.md]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from continuum_sim.configio import atomic_write_text  # noqa: E402
from continuum_sim.model.stiffness import strain_limited_geometry  # noqa: E402
from continuum_sim.scenario.config import ScenarioConfig  # noqa: E402
from continuum_sim.sweep.evaluations import GravitySag  # noqa: E402
from continuum_sim.sweep.static import evaluate_static  # noqa: E402

POSES = {"planar (60,0,30,0,0,0)°": (60, 0, 30, 0, 0, 0), "spatial (45,30,60,200,50,100)°": (45, 30, 60, 200, 50, 100)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="also write the table to this Markdown file")
    args = parser.parse_args(argv)
    lines: list[str] = []

    def emit(line: str) -> None:
        print(line, flush=True)
        lines.append(line)

    base = ScenarioConfig.default()
    on_axis = dataclasses.replace(base.arm, sections=tuple(dataclasses.replace(s, leaf_radius=0.0) for s in base.arm.sections))
    leaves = {"on axis (r = 0)": on_axis, "strain-limited": strain_limited_geometry(on_axis)}
    emit("| pose | leaves | joint | tool error without gravity (mm) | with gravity (mm) | max cable tension (N) |")
    emit("|---|---|---|---|---|---|")
    for pose_name, pose in POSES.items():
        for leaf_name, arm in leaves.items():
            for joint, central in (("hinge_pair", "universal"), ("hinge_triple", "ball")):
                config = dataclasses.replace(
                    base, arm=dataclasses.replace(arm, central_joint=central), model=dataclasses.replace(base.model, joint=joint)
                )
                r = evaluate_static(config, GravitySag(q_deg=pose, tool="grinder", settle_s=3.0))
                emit(
                    f"| {pose_name} | {leaf_name} | {joint} ({central}) | {r['shape_error_mm']:.2f} | {r['pcc_error_mm']:.2f} "
                    f"| {r['max_cable_tension_n']:.1f} |"
                )
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out, "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
