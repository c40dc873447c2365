"""Attribution of the open loop's failure: switch one suspected cause off at a time, then combined.

    python scripts/attribution_open_loop.py [--workers 2] [--out docs/calibration]

Writes <out>/attribution_open_loop.json and attribution_open_loop.md (the table in
docs/calibration.md). Resumable: variants already in the JSON are not run again.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from variant_runs import markdown_table, run_variants

OPEN = {"control.mode": "open"}
GRAVITY_OFF = {"model.gravity": False}
MU_0 = {"model.cable_friction.mu": 0.0}
CONTACT_OFF = {"scene.gripper_plate_contact": False}
# Every planned move at half speed: joint transfers (the gripper's approach), Cartesian moves
# (its grasp runs at fast_speed / 2) and their accelerations.
SLOW = {"plan.joint_speed_deg_s": 10.0, "plan.joint_accel_deg_s2": 20.0, "plan.fast_speed": 0.02, "plan.max_accel": 0.1}

VARIANTS = [
    ("as shipped", {}),
    ("gravity off", GRAVITY_OFF),
    ("μ = 0", MU_0),
    ("gripper–plate contact off", CONTACT_OFF),
    ("approach speed halved", SLOW),
    ("gravity off + μ = 0", {**GRAVITY_OFF, **MU_0}),
    ("gravity off + contact off", {**GRAVITY_OFF, **CONTACT_OFF}),
    ("μ = 0 + contact off", {**MU_0, **CONTACT_OFF}),
    ("μ = 0 + speed halved", {**MU_0, **SLOW}),
    ("all four", {**GRAVITY_OFF, **MU_0, **CONTACT_OFF, **SLOW}),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="docs/calibration")
    ap.add_argument("--keep", default=None, help="also write each variant's run folder under this folder")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    variants = [(name, {**OPEN, **ov}) for name, ov in VARIANTS]
    rows = run_variants(variants, out / "attribution_open_loop.json", args.workers, args.keep)
    for r in rows:  # the table shows the switches, not the common open-loop setting
        r["overrides"] = {k: v for k, v in r["overrides"].items() if k not in OPEN}
    table = markdown_table(rows)
    (out / "attribution_open_loop.md").write_text(table)
    print(table)


if __name__ == "__main__":
    main()
