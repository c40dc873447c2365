"""Tendon-angle calibration from single-tendon pulls: the first step of ``identify --calibrate-angles``.

A pulled tendon bends the robot toward itself, so the tip's largest deflection in a pull
(rows labelled ``rep<N>_tendon<X>_id<Y>_pull``) points along tendon X's angle about the
backbone in the recording's frame (``opencr.tendon_angles_deg``). The measured angles
replace ``arm.sections.k.cable_angles_deg`` (offsets reset to 0) before the fit; tendons
without a pull keep their angles.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..configio import ConfigError, replace_path
from ..scenario.config import ScenarioConfig
from .data import Recording
from .opencr import PULL, tendon_angles_deg


def calibrate_angles(config: ScenarioConfig, rec: Recording, source: str) -> tuple[ScenarioConfig, dict[str, Any]]:
    """``config`` with the cable angles measured from ``rec``'s pull rows; and what was done."""
    labels = rec.labels or []
    rows = np.array([PULL.match(label) is not None for label in labels], dtype=bool)
    if not rows.any():
        raise ConfigError("--calibrate-angles", f"{source} has no single-tendon pull rows (labels rep<N>_tendon<X>_id<Y>_pull)")
    pulled = [labels[i] for i in np.flatnonzero(rows)]
    angles = tendon_angles_deg(pulled, rec.position[rows] * 1000.0, rec.n_cables)
    before = [list(s.cable_angles_deg) for s in config.arm.sections]
    for k, section in enumerate(config.arm.sections):
        measured = [float(a) if np.isfinite(a) else float(b) for a, b in zip(angles[k], np.asarray(section.cable_angles_deg)
                                                                               + section.cable_angle_offset_deg)]
        try:
            config = replace_path(config, f"arm.sections.{k}.cable_angle_offset_deg", 0.0)
            config = replace_path(config, f"arm.sections.{k}.cable_angles_deg", tuple(round(a, 2) for a in measured))
        except ConfigError as exc:
            raise ConfigError("--calibrate-angles", f"section {k}: measured angles {measured} are not valid ({exc.message})") from None
    return config, {"source": source, "pull_rows": int(rows.sum()),
                    "method": "direction of the largest tip deflection per single-tendon pull (circular mean over repetitions)",
                    "before_deg": before, "after_deg": [list(s.cable_angles_deg) for s in config.arm.sections],
                    "missing": [int(i) for i in np.flatnonzero(~np.isfinite(angles.ravel()))]}
