"""The foam's connectivity check on the default grid: the flood fill (``plant.foam.held_anchored``,
production) against a labelling of the whole grid (``scipy.ndimage.label``, its test oracle),
CPU ms per check, on a plate cut across but for a one-voxel bridge (the check's common case:
still anchored). Prints JSON.

    python benchmarks/connectivity.py
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable

import numpy as np
from scipy import ndimage

from continuum_sim.layout import TaskLayout
from continuum_sim.model.scene_options import FoamOptions
from continuum_sim.plant import foam


def _cpu_ms(f: Callable[[], object], n: int) -> float:
    f()
    start = time.process_time()
    for _ in range(n):
        f()
    return (time.process_time() - start) / n * 1e3


def main() -> None:
    grid = foam.plate_grid(TaskLayout(), FoamOptions().voxel_size)
    material = grid.material
    material[material.shape[0] // 4, :, :] = False
    material[material.shape[0] // 4, -1, -1] = True  # the bridge
    held = np.array([(material.shape[0] - 5) * material.shape[1] + material.shape[1] // 2], np.int64)
    assert foam.held_anchored(material, held) == 1
    flood, label = _cpu_ms(lambda: foam.held_anchored(material, held), 200), _cpu_ms(lambda: ndimage.label(material), 20)
    print(json.dumps({"grid": list(material.shape), "flood_fill_ms": flood, "ndimage_label_ms": label,
                      "label_over_flood": label / flood}, indent=1))


if __name__ == "__main__":
    main()
