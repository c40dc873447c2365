"""Segment stiffness per section: analytic model vs the independent FE model, and what it takes to bend 90°.

Prints Markdown tables for docs/model.md (analytic vs FE; per section at 90°; holding tensions on the MuJoCo
model) and, with ``--out``, writes them to a file and their numbers to a JSON beside it (``--json``):

    python scripts/segment_stiffness_table.py [--out docs/model/segment_stiffness.md] [--json docs/model/segment_stiffness.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from continuum_sim.configio import atomic_write_text  # noqa: E402
from continuum_sim.geometry import ArmGeometry  # noqa: E402
from continuum_sim.model.stiffness import (  # noqa: E402
    bend_tension,
    leaf_peak_strain,
    section_bending_rigidity,
    segment_stiffness,
    strain_limited_geometry,
    strain_limited_leaf_radius,
)
from continuum_sim.validation.fe_segment import LeafSection, SegmentFE  # noqa: E402

NAMES = ("proximal", "middle", "distal")
SLUGS = {"on axis (r = 0)": "on_axis", "strain-limited": "strain_limited", "r = 8 mm": "r_8mm", "at cable radius (15 mm)": "cable_radius"}


def _with_radius(geometry: ArmGeometry, radius: float | None) -> ArmGeometry:
    if radius is None:
        return geometry
    return dataclasses.replace(geometry, sections=tuple(dataclasses.replace(s, leaf_radius=radius) for s in geometry.sections))


def fe(geometry: ArmGeometry, k: int):
    s = geometry.sections[k]
    leaf = LeafSection(s.hinge_width, s.hinge_thickness, geometry.material.youngs_modulus, geometry.material.poisson_ratio)
    return SegmentFE(leaf, s.leaf_length(geometry.disk_thickness), s.leaf_radius, s.leaf_angles_deg, joint="ball").stiffness()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="also write the tables to this Markdown file")
    parser.add_argument("--json", type=Path, help="also write the tables' numbers to this JSON file")
    args = parser.parse_args(argv)
    lines: list[str] = []
    data: dict = {"fe": {}, "sections": {}, "holding": {}}
    base = dataclasses.replace(ArmGeometry(), central_joint="ball")
    emit = lines.append  # every table line goes to stdout and to --out
    emit("| layout | section | leaf r (mm) | K_x analytic | K_x FE | K_y analytic | K_y FE | K_twist analytic | K_twist FE | max dev |")
    emit("|---|---|---|---|---|---|---|---|---|---|")
    layouts = {"on axis (r = 0)": _with_radius(base, 0.0), "strain-limited": strain_limited_geometry(base)}
    layouts["r = 8 mm"] = _with_radius(base, 0.008)
    layouts["at cable radius (15 mm)"] = _with_radius(base, 0.015)
    for name, geometry in layouts.items():
        for k, s in enumerate(geometry.sections):
            a = segment_stiffness(geometry, s)
            f = fe(geometry, k)
            dev = max(abs(a[i] / f[i, i] - 1.0) for i in range(3))
            data["fe"].setdefault(SLUGS[name], {})[NAMES[k]] = {
                "leaf_radius_mm": s.leaf_radius * 1e3, "kx_analytic": a[0], "kx_fe": f[0, 0], "ky_analytic": a[1], "ky_fe": f[1, 1],
                "ktwist_analytic": a[2], "ktwist_fe": f[2, 2], "max_dev_pct": 100 * dev,
            }
            emit(
                f"| {name} | {NAMES[k]} | {s.leaf_radius * 1e3:.1f} | {a[0]:.4g} | {f[0, 0]:.4g} | {a[1]:.4g} | {f[1, 1]:.4g} "
                f"| {a[2]:.4g} | {f[2, 2]:.4g} | {100 * dev:.2f} % |"
            )
    data["fe_max_dev_pct"] = max(v["max_dev_pct"] for layout in data["fe"].values() for v in layout.values())
    emit("")
    emit("| section | r_max (mm) | leaf r (mm) | peak strain at 90° | K_bend (N·m/rad) | EI_sec (N·m²) | K_twist ball (N·m/rad) "
         "| T to hold 90° (N) | ×1/cos 30° (N) |")
    emit("|---|---|---|---|---|---|---|---|---|")
    for name, geometry in (("on axis (r = 0)", _with_radius(base, 0.0)), ("strain-limited", strain_limited_geometry(base))):
        for k, s in enumerate(geometry.sections):
            kx, _, kz = segment_stiffness(geometry, s)
            t = bend_tension(geometry, k)
            data["sections"].setdefault(SLUGS[name], {})[NAMES[k]] = {
                "r_max_mm": strain_limited_leaf_radius(geometry, s) * 1e3, "leaf_radius_mm": s.leaf_radius * 1e3,
                "peak_strain_pct": 100 * leaf_peak_strain(geometry, s), "k_bend": kx, "ei_section": section_bending_rigidity(geometry, s),
                "k_twist_ball": kz, "bend_tension_n": t, "bend_tension_worst_n": t / math.cos(math.radians(30)),
            }
            emit(
                f"| {name}: {NAMES[k]} | {strain_limited_leaf_radius(geometry, s) * 1e3:.2f} | {s.leaf_radius * 1e3:.1f} "
                f"| {100 * leaf_peak_strain(geometry, s):.2f} % | {kx:.4g} | {section_bending_rigidity(geometry, s):.4g} "
                f"| {kz:.4g} | {t:.1f} | {t / math.cos(math.radians(30)):.1f} |"
            )
    cable = _with_radius(base, 0.015)
    data["cable_radius_proximal"] = {"peak_strain_pct": 100 * leaf_peak_strain(cable, cable.sections[0]),
                                     "bend_tension_n": bend_tension(cable, 0)}
    emit("")
    data["holding"] = holding_table(base, emit)
    text = "\n".join(lines) + "\n"
    sys.stdout.write(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out, text)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.json, json.dumps(data, indent=2) + "\n")
    return 0


def holding_table(base: ArmGeometry, emit=print) -> dict:
    """Least cable tensions holding 90° on the MuJoCo model (gravity off), worst over bending directions (printed and returned)."""
    import numpy as np

    from continuum_sim.glbackend import choose_gl_backend
    from continuum_sim.model.arm import build_single_arm_model
    from continuum_sim.model.holding import holding_tensions
    from continuum_sim.model.options import ModelOptions

    choose_gl_backend()
    import mujoco

    options = ModelOptions(joint="ball")
    emit("| segments | section at 90° (others straight): worst tension over directions (N) | all three at 90°, worst S-shape (N) |")
    emit("|---|---|---|")
    data: dict = {}
    for name, geometry in (("on axis (r = 0)", _with_radius(base, 0.0)), ("strain-limited", strain_limited_geometry(base))):
        model = mujoco.MjModel.from_xml_string(build_single_arm_model(geometry, options, gravity=False).to_xml_string())
        single = []
        for k, s in enumerate(geometry.sections):
            worst = 0.0
            for phi in np.arange(0.0, 120.0, 15.0):
                q = np.zeros(6)
                q[2 * k], q[2 * k + 1] = s.max_bend, math.radians(s.cable_angles_deg[0] + phi)
                worst = max(worst, float(holding_tensions(model, geometry, q, "ball")[0].max()))
            single.append(f"{NAMES[k]} {worst:.1f}")
            data.setdefault(SLUGS[name], {})[NAMES[k]] = worst
        combined = 0.0
        for p0 in range(0, 120, 30):
            for d1 in (0, 90, 180, 270):
                for d2 in (0, 90, 180, 270):
                    q = np.radians([90, p0, 90, p0 + d1, 90, p0 + d1 + d2])
                    combined = max(combined, float(holding_tensions(model, geometry, q, "ball")[0].max()))
        emit(f"| {name} | {', '.join(single)} | {combined:.1f} |")
        data[SLUGS[name]]["s_shape"] = combined
    return data


if __name__ == "__main__":
    sys.exit(main())
