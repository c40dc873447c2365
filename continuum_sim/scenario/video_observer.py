"""The run's video as a tick-loop observer: frames of the simulation's state at the video's rate,
the kerf as cut (the run's ``FoamCutter`` grid, ``Simulation.cutter``) and the overlay's figures.

The drawing itself is ``continuum_sim.video`` (render workers); docs/video.md says what it shows.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .simulate import Observer, Simulation


class VideoObserver(Observer):
    """Streams frames into ``video.mp4`` at the configured rate of simulated time: the kerf as
    cut (``sim.cutter``'s voxels) and, with ``video_overlay``, the cut's figures over the frames."""

    def __init__(self, sim: Simulation, path: Any, simulation_config: Any, model: Any = None, *,
                 fps: float | None = None, workers: int | None = None, progress: bool = False) -> None:
        """``model``: the model to draw (default ``sim.model``; the spatial twin of a native-cable model);
        ``fps`` (default ``video_fps``) and ``workers`` (``VideoRecorder``'s) for other uses than the run's video;
        ``progress``: a bar over the frames still encoding when the physics is done (the render workers lag)."""
        from ..video import VideoRecorder

        c = simulation_config
        self.render_model = sim.drawable_model if model is None else model
        self.cutter = sim.cutter
        self.overlay = bool(c.video_overlay)
        self.video = VideoRecorder(self.render_model, path, c.cameras, c.video_width, c.video_height,
                                   c.video_fps if fps is None else fps, shadows=c.video_shadows, workers=workers,
                                   grid=None if self.cutter is None else self.cutter.grid)
        self.progress = progress
        self._force = [0.0, 0]  # |cutting force| summed over the ticks since the last frame, ticks

    def after_tick(self, sim: Simulation) -> str | None:
        if self.overlay and self.cutter is not None:
            self._force[0] += float(np.linalg.norm(self.cutter.state.force))
            self._force[1] += 1
        if not self.video.due(sim.data):
            return None
        if self.render_model is not sim.model:
            self.render_model.geom_rgba[:] = sim.model.geom_rgba  # colours the run changed (cut material)
        self.video.maybe_capture(sim.data, self._overlay_text(sim) if self.overlay else ())
        return None

    def _overlay_text(self, sim: Simulation) -> tuple[str, ...]:
        force = self._force[0] / max(self._force[1], 1)
        self._force = [0.0, 0]
        return overlay_text(sim, force)

    def close(self, sim: Simulation) -> None:  # noqa: ARG002 - the hook's signature
        try:
            if self.progress:
                from tqdm import tqdm

                with tqdm(total=self.video.frames, unit="frame", desc="video") as bar:
                    self.video.wait_for_workers(bar.update)
        finally:
            self.video.close()


def overlay_text(sim: Simulation, cutting_force: float) -> tuple[str, ...]:
    """The video overlay's lines for the current state (``video_overlay``); ``cutting_force``: N."""
    from ..video_overlay import OverlayValues, overlay_lines

    c, nan = sim.cutter, float("nan")
    plan = sim.plan
    values = OverlayValues(
        time=float(sim.data.time),
        stage=str(plan.stage_names[int(plan.stage[sim.plan_index])]),
        cut_fraction=nan if c is None or c.n_cells == 0 else 1.0 - c.cells_remaining / c.n_cells,
        spindle_speed=nan if c is None else abs(c.spindle_speed),
        cutting_force=nan if c is None else cutting_force,
        detached=bool(c is not None and c.detached),
    )
    return overlay_lines(values)
