"""The default run's Rerun recording: its size, frames, entities and kerf columns, for docs/report.md.

    python scripts/replay_figures.py RUN_DIR --out docs/results/replay_export.json   # ~10 s CPU

Writes ``RUN_DIR/replay.rrd`` as ``continuum-sim export RUN_DIR --rerun`` does
(``report.rerun_export.export_rerun``, which reads ``trajectory.npz`` and ``config.toml`` only)
and stores its summary: ``frames``, ``entities`` (how many), ``kerf_columns``, ``megabytes``.
Needs the ``replay`` extra (rerun-sdk).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from continuum_sim.configio import atomic_write_text  # noqa: E402
from continuum_sim.report.rerun_export import export_rerun, require_rerun  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("run_dir", type=Path, help="a run folder (trajectory.npz, config.toml)")
    parser.add_argument("--out", type=Path, required=True, help="JSON file to write")
    args = parser.parse_args()
    require_rerun()
    s = export_rerun(args.run_dir, args.run_dir / "replay.rrd")
    result = {"frames": s["frames"], "entities": len(s["entities"]), "kerf_columns": s["kerf_columns"],
              "kerf_timed": s["kerf_timed"], "megabytes": s["bytes"] / 1e6}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out, json.dumps(result, indent=2, sort_keys=True) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
