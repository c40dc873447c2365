"""Off-screen MP4 recording of a running simulation (EGL + imageio-ffmpeg).

One ``mujoco.Renderer`` renders every requested camera into the same frame, side by
side; frames stream straight into ffmpeg (no frame list in memory) and the MP4 appears
at its final path only when it is complete (written under a temporary name, renamed on
close). Use it as a context manager so the GL context and the encoder are always freed.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np

from .glbackend import choose_gl_backend


class VideoRecorder:
    """Capture frames at ``fps`` of simulated time from named cameras, tiled horizontally."""

    def __init__(
        self,
        model,
        path: str | os.PathLike[str],
        cameras: Sequence[str],
        width: int = 640,
        height: int = 480,
        fps: float = 25.0,
        shadows: bool = False,
    ) -> None:
        """``shadows`` off by default: software GL (Mesa llvmpipe on CPU-only machines)
        spends ~3× longer per frame on shadow maps and multisampling than on the scene."""
        choose_gl_backend()
        import imageio.v2 as imageio
        import mujoco

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.with_name(f".{self.path.stem}.partial{self.path.suffix}")
        self.cameras = list(cameras)
        for name in self.cameras:
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name) < 0:
                raise ValueError(f"cameras: unknown camera {name!r}")
        # The offscreen buffer must hold the frame; grow it if the model asks for less.
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        if not shadows:
            model.light_castshadow[:] = 0
            model.vis.quality.offsamples = 0
        self._renderer = mujoco.Renderer(model, height, width)
        self._writer = imageio.get_writer(
            self._tmp, format="FFMPEG", mode="I", fps=fps, codec="libx264", quality=7, macro_block_size=8,
            ffmpeg_log_level="error",
        )
        self.period = 1.0 / fps
        self.next_time = 0.0
        self.frames = 0
        self._closed = False

    def render_frame(self, data) -> np.ndarray:
        """The tiled RGB frame of the current state."""
        tiles = []
        for name in self.cameras:
            self._renderer.update_scene(data, camera=name)
            tiles.append(self._renderer.render())
        return np.concatenate(tiles, axis=1)

    def maybe_capture(self, data) -> bool:
        """Append a frame if simulated time has reached the next frame time."""
        if data.time + 1e-12 < self.next_time:
            return False
        self._writer.append_data(self.render_frame(data))
        self.frames += 1
        self.next_time += self.period
        return True

    def close(self, keep: bool = True) -> None:
        """Finish the file; with ``keep`` it is moved to its final name, else discarded."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.close()
        finally:
            self._renderer.close()
        if keep and self.frames > 0:
            os.replace(self._tmp, self.path)
        elif self._tmp.exists():
            self._tmp.unlink()

    def __enter__(self) -> "VideoRecorder":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        # A run that stopped early still keeps what was rendered (SPEC: keep what was computed).
        self.close(keep=True)
