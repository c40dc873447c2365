"""Text over the video's frames: simulated time, task stage, cut progress, spindle speed, cutting force.

The simulation process formats the lines (``overlay_lines``, a pure function of the values
it read at the frame's time) and sends them with the frame's state; the render worker draws
them (``draw_overlay``, Pillow) in the top-left corner of the first camera's tile, on a dark
translucent box, so the cut close-up (the second tile) stays unobstructed.
On by default (``simulation.video_overlay``; ``continuum-sim run --video --no-overlay``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np


@dataclass(frozen=True)
class OverlayValues:
    """What the overlay shows at one frame (SI units; NaN: not known in this run)."""

    time: float  # s
    stage: str  # plan stage name
    cut_fraction: float  # of the planned kerf's voxel columns cleared, 0..1
    spindle_speed: float  # rad/s
    cutting_force: float  # N, mean magnitude on the cutter since the previous frame
    detached: bool  # the sample is free of the plate


def overlay_lines(v: OverlayValues) -> tuple[str, ...]:
    """The overlay's text lines for ``v``."""
    rpm = v.spindle_speed * 60.0 / (2.0 * math.pi)
    lines = [f"t {v.time:5.1f} s   {v.stage}"]
    if not math.isnan(v.cut_fraction):
        state = "sample free" if v.detached else "sample held by the plate"
        lines.append(f"cut {100.0 * v.cut_fraction:3.0f} %   {state}")
    if not math.isnan(v.spindle_speed):
        lines.append(f"spindle {rpm:6.0f} rpm   force {v.cutting_force:5.3f} N")
    return tuple(lines)


@cache
def _font(size: int) -> Any:
    from PIL import ImageFont

    return ImageFont.load_default(size=size)


def draw_overlay(frame: np.ndarray, lines: tuple[str, ...], tile_height: int) -> np.ndarray:
    """``frame`` (H, W, 3 uint8) with ``lines`` in its top-left corner (a new array)."""
    if not lines:
        return frame
    from PIL import Image, ImageDraw

    size = max(10, round(tile_height / 30))
    font = _font(size)
    pad, step = size // 2, round(1.3 * size)
    measure = ImageDraw.Draw(Image.new("L", (1, 1)))
    width = max(measure.textbbox((0, 0), line, font=font)[2] for line in lines) + 2 * pad
    height = len(lines) * step + 2 * pad - (step - size)
    width, height = min(width, frame.shape[1]), min(height, frame.shape[0])
    # Only the box's pixels are composited (the whole frame costs ~5x more).
    box = Image.fromarray(np.ascontiguousarray(frame[:height, :width])).convert("RGBA")
    layer = Image.new("RGBA", box.size, (0, 0, 0, 150))
    draw = ImageDraw.Draw(layer)
    for k, line in enumerate(lines):
        draw.text((pad, pad + k * step), line, font=font, fill=(255, 255, 255, 255))
    out = frame.copy()
    out[:height, :width] = np.asarray(Image.alpha_composite(box, layer).convert("RGB"))
    return out
