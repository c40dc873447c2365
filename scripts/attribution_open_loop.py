"""Attribution of the open loop's failure: switch one suspected cause off at a time, then combined.

    python scripts/attribution_open_loop.py --plan before [--workers 2] [--out docs/calibration]
    python scripts/attribution_open_loop.py --plan shipped

--plan before: on the plan as it was before issue 24's knock fix (pre-grasp 35 mm back along
the tilted tool axis, docs/calibration/knock_before.toml), where the open loop dropped the
sample; --plan shipped: on the shipped plan. Writes <out>/attribution_open_loop_<plan>.json and
.md (the tables in docs/calibration.md). Resumable: variants already in the JSON are not run again.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from variant_runs import markdown_table, run_variants

OPEN = {"control.mode": "open"}
PLAN_BEFORE = {"plan.pregrasp_direction": "tool_axis", "plan.pregrasp_distance": 0.035}
GRAVITY_OFF = {"model.gravity": False}
MU_0 = {"model.cable_friction.mu": 0.0}
CONTACT_OFF = {"scene.gripper_plate_contact": False}
# Every planned move at half speed: joint transfers (the gripper's approach), Cartesian moves
# (its grasp runs at fast_speed / 2) and their accelerations.
SLOW = {"plan.joint_speed_deg_s": 10.0, "plan.joint_accel_deg_s2": 20.0, "plan.fast_speed": 0.02, "plan.max_accel": 0.1}

VARIANTS = [
    ("baseline", {}),
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
    ap.add_argument("--plan", choices=("before", "shipped"), default="shipped")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="docs/calibration")
    ap.add_argument("--keep", default=None, help="also write each variant's run folder under this folder")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    common = {**OPEN, **(PLAN_BEFORE if args.plan == "before" else {})}
    variants = [(name, {**common, **ov}) for name, ov in VARIANTS]
    rows = run_variants(variants, out / f"attribution_open_loop_{args.plan}.json", args.workers, args.keep)
    for r in rows:  # the table shows the switches, not the common settings
        r["overrides"] = {k: v for k, v in r["overrides"].items() if k not in common}
    table = markdown_table(rows)
    (out / f"attribution_open_loop_{args.plan}.md").write_text(table)
    print(table)


if __name__ == "__main__":
    main()
