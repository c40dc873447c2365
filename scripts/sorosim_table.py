"""SoRoSim statics over link counts and joint kinds: Markdown table + JSON (atomic writes).

    python scripts/sorosim_table.py --links 10 20 40 80 --out validation/sorosim_table

writes ``<out>.md`` and ``<out>.json`` and prints the table. Progress goes to stderr.
``--merge`` keeps the rows already in ``<out>.json`` and replaces only those recomputed
(same rod, joint and link count), e.g. to add the scenario's joint type:

    python scripts/sorosim_table.py --joints hinge_pair --merge
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import get_args

# Small dense solves: BLAS threads only contend (set before numpy is imported).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from continuum_sim.configio import ConfigError, atomic_write_text
from continuum_sim.glbackend import choose_gl_backend
from continuum_sim.model.rod import RodJoint
from continuum_sim.validation.sorosim import (
    RODS,
    RodStatics,
    load_statics,
    markdown_table,
    subset,
    summarise,
)

_JOINT_ORDER = ("ball_twist", "ball", "hinge_triple", "hinge_pair")


def args_order(joint: str) -> int:
    """Table order of joint kinds (the original rows first, the scenario's hinge pair last)."""
    return _JOINT_ORDER.index(joint) if joint in _JOINT_ORDER else len(_JOINT_ORDER)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rods", nargs="+", default=list(RODS), choices=list(RODS))
    parser.add_argument("--links", nargs="+", type=int, default=[10, 20, 40, 80])
    parser.add_argument("--joints", nargs="+", default=["ball_twist", "ball", "hinge_triple", "hinge_pair"], choices=get_args(RodJoint))
    parser.add_argument("--cases", type=int, default=500, help="cases per rod (a seeded subset when fewer than 500)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--merge", action="store_true", help="keep the other rows of an existing <out>.json")
    parser.add_argument("--out", type=Path, default=Path("validation/sorosim_table"), help="output path without suffix")
    args = parser.parse_args(argv)
    choose_gl_backend()
    from tqdm import tqdm

    rows = []
    try:
        for rod_name in args.rods:
            rod = RODS[rod_name]
            cases = subset(load_statics(rod), args.cases, args.seed)
            for joint in args.joints:
                for n_links in args.links:
                    statics = RodStatics(rod.spec(n_links, joint))
                    start = time.perf_counter()
                    errors = [statics.error(c) for c in tqdm(cases, desc=f"{rod.name} {joint} n={n_links}", leave=False)]
                    rows.append(summarise(rod, statics.spec, errors, time.perf_counter() - start))
                    tqdm.write(markdown_table(rows[-1:]).splitlines()[-1], file=sys.stderr)
    except ConfigError as exc:
        print(f"sorosim_table: error: {exc}", file=sys.stderr)
        return 2
    if args.merge and args.out.with_suffix(".json").is_file():
        key = lambda r: (r["rod"], r["joint"], r["n_links"])
        fresh = {key(r) for r in rows}
        old = [r for r in json.loads(args.out.with_suffix(".json").read_text()) if key(r) not in fresh]
        rows = sorted(old + rows, key=lambda r: (r["rod"], args_order(r["joint"]), r["n_links"]))
    table = markdown_table(rows)
    atomic_write_text(args.out.with_suffix(".md"), table)
    atomic_write_text(args.out.with_suffix(".json"), json.dumps(rows, indent=2) + "\n")
    print(table, end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
