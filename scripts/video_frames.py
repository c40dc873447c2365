"""Frames of a run's video at given simulated times, as PNG files (to look at the video without a player).

    python scripts/video_frames.py runs/default [--times 5 12 24 36 40 45] [--out runs/default/frames]

Reads ``RUN_DIR/video.mp4`` (frame k shows simulated time k / video_fps, ``RUN_DIR/config.toml``)
and writes ``frame_<t>s.png`` for each time.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from continuum_sim.scenario.config import ScenarioConfig


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--times", type=float, nargs="+", default=[5, 12, 24, 36, 40, 45])
    parser.add_argument("--out", type=Path, help="folder for the PNGs (default: RUN_DIR/frames)")
    args = parser.parse_args()
    import imageio.v2 as imageio

    fps = ScenarioConfig.from_toml(args.run_dir / "config.toml").simulation.video_fps
    out = args.out or args.run_dir / "frames"
    out.mkdir(parents=True, exist_ok=True)
    reader = imageio.get_reader(args.run_dir / "video.mp4")
    try:
        for t in args.times:
            path = out / f"frame_{t:g}s.png"
            imageio.imwrite(path, reader.get_data(round(t * fps)))
            print(path)
    finally:
        reader.close()


if __name__ == "__main__":
    main()
