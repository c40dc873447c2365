"""How much a run's video changes over the planned kerf between two times (is the cut visible?).

    python scripts/kerf_visibility.py RUN_DIR [--times 12 36] [--camera closeup]

Reads ``RUN_DIR/video.mp4``, the run's own model (``RUN_DIR/model/scene.xml``: its cameras) and
configuration (``config.toml``: the kerf, the frame rate, the tiles), projects the planned kerf's
top face into the camera's tile (``video_foam.kerf_region``) and prints the mean absolute change
of those pixels (0-255, mean over RGB) between the two times: the figure
tests/test_video_kerf.py asserts on (docs/video.md).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from continuum_sim.glbackend import choose_gl_backend


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--times", type=float, nargs=2, default=[12.0, 36.0])
    parser.add_argument("--camera", default="closeup")
    args = parser.parse_args()
    choose_gl_backend()
    import imageio.v2 as imageio
    import mujoco

    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.video_foam import kerf_region

    config = ScenarioConfig.from_toml(args.run_dir / "config.toml")
    sim = config.simulation
    w, h = sim.video_width, sim.video_height
    tile = list(sim.cameras).index(args.camera)
    model = mujoco.MjModel.from_xml_path(str(args.run_dir / "model" / "scene.xml"))
    plate = config.layout.plate
    region = kerf_region(model, args.camera, plate.kerf_polyline(), plate.kerf_width, w, h)
    reader = imageio.get_reader(args.run_dir / "video.mp4")
    try:
        a, b = (reader.get_data(round(t * sim.video_fps)).astype(float)[:, tile * w:(tile + 1) * w] for t in args.times)
    finally:
        reader.close()
    change = np.abs(b - a).mean(axis=2)[region].mean()
    print(f"{args.camera}: kerf region {100 * region.mean():.1f} % of the tile; mean change "
          f"{args.times[0]:g} s -> {args.times[1]:g} s: {change:.1f} (of 255)")


if __name__ == "__main__":
    main()
