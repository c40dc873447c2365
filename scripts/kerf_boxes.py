"""How many boxes the video's kerf needs during the default run (``video_foam.KerfVoxels.boxes``).

    python scripts/kerf_boxes.py [--every 0.5] [--out docs/video/kerf_boxes.json]

Runs the shipped default scenario (no video) with an observer that merges the kerf band's
voxels into boxes every ``--every`` simulated seconds, as a render worker does for a frame,
and prints the counts (docs/video.md). ``--out`` also writes them as JSON: ``uncut_boxes``
(the band before the cut), ``max_boxes`` and the first time it is reached (``max_at_s``),
``end_boxes`` (at the run's end) and every count (``counts``: time, boxes).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.scenario.runner import run_scenario
from continuum_sim.scenario.simulate import Observer, Simulation
from continuum_sim.video_foam import KerfVoxels


class BoxCount(Observer):
    def __init__(self, every: float) -> None:
        self.every, self.next = every, 0.0
        self.counts: list[tuple[float, int]] = []

    def start(self, sim: Simulation) -> None:
        kerf = KerfVoxels.from_model(sim.drawable_model, sim.cutter.grid)
        assert kerf is not None
        self.kerf = kerf

    def after_tick(self, sim: Simulation) -> str | None:
        if sim.data.time + 1e-9 >= self.next:
            self.next += self.every
            material = sim.cutter.grid.material
            self.counts.append((round(float(sim.data.time), 2), len(self.kerf.boxes(self.kerf.snapshot(material)))))
        return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--every", type=float, default=0.5, help="simulated seconds between counts")
    parser.add_argument("--out", type=Path, default=None, help="also write the counts as JSON here")
    args = parser.parse_args()
    counter = BoxCount(args.every)
    run_scenario(ScenarioConfig.default(), None, observers=[counter])
    print("time_s boxes")
    for t, n in counter.counts:
        print(f"{t:6.2f} {n}")
    most = max(n for _, n in counter.counts)
    print(f"max {most} boxes")
    if args.out is not None:
        summary = {"every_s": args.every, "uncut_boxes": counter.counts[0][1], "max_boxes": most,
                   "max_at_s": next(t for t, n in counter.counts if n == most), "end_boxes": counter.counts[-1][1],
                   "counts": [{"time_s": t, "boxes": n} for t, n in counter.counts]}
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(summary, indent=1) + "\n")


if __name__ == "__main__":
    main()
