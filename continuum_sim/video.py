"""Off-screen MP4 recording of a running simulation (EGL + imageio-ffmpeg), rendered off the physics path.

The simulation only *snapshots* what a frame needs (time, qpos, mocap poses, the geom
colours that the run changes, e.g. cut material turning invisible) at ``fps`` of simulated
time. Chunks of snapshots go to render worker processes, each of which owns its own
``mujoco.Renderer`` (an EGL context per process) and encodes its chunk to an MP4 segment;
``close`` joins the segments without re-encoding (ffmpeg concat demuxer) and moves the
result to its final name atomically. Rendering therefore runs beside the physics instead
of inside the tick loop, and on several cores.

With the cutter's voxel grid (``grid``) each snapshot also carries the kerf band's voxels
(packed bits, only when they changed) and the workers draw what is left of the band instead
of its static geoms (``video_foam``), so the cut shows as it is made; overlay lines sent with
a frame are drawn over it (``video_overlay``). What the video shows: docs/video.md.

Why: software EGL (Mesa llvmpipe on CPU-only machines) spends ~0.1 s per two-camera frame,
most of it tessellating the 18 cable tendons (measured: 0.088 s vs 0.037 s per view with
tendons hidden); the default run has ~1,000 frames. ``quality`` lowers MuJoCo's
tessellation for the video (``numslices``/``numstacks``), which halves the frame cost and
is invisible at 0.8 mm cable width; ``workers=0`` renders in-process (the old path, kept
for comparison and for machines where spawning processes is not wanted).
"""

from __future__ import annotations

import os
import pickle
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from .video_foam import KerfVoxels
from .video_overlay import draw_overlay

# Tessellation used for the video: MuJoCo's defaults are (28, 16); thin cables and 40 mm
# disks look the same at 640×480 with (14, 6), and software GL renders ~2× faster.
VIDEO_SLICES = {"fast": (14, 6), "fine": (28, 16)}


@dataclass(frozen=True)
class FrameState:
    """Everything a frame needs from the simulation: the rest comes from the model."""

    time: float
    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    geom_rgba: np.ndarray | None  # None: unchanged since the previous snapshot
    foam: np.ndarray | None = None  # the kerf band's voxels (KerfVoxels.snapshot); None: unchanged
    text: tuple[str, ...] = ()  # overlay lines (video_overlay.overlay_lines)


def _prepare_model(model: Any, width: int, height: int, shadows: bool, quality: str) -> None:
    """Offscreen buffer large enough for the frame; shadows/MSAA off unless asked; tessellation."""
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    if not shadows:
        model.light_castshadow[:] = 0
        model.vis.quality.offsamples = 0
    slices, stacks = VIDEO_SLICES[quality]
    model.vis.quality.numslices = slices
    model.vis.quality.numstacks = stacks


def pose_for_drawing(model: Any, data: Any, time: float, qpos: np.ndarray, mocap_pos: np.ndarray,
                     mocap_quat: np.ndarray, geom_rgba: np.ndarray | None = None) -> None:
    """Put a state into ``data`` of the model that draws it and compute what drawing needs.

    ``model`` may be another model of the same state layout than the one simulated (the
    spatial twin of a native-cable run, whose cables MuJoCo draws); ``geom_rgba`` carries the
    colours the run changed (cut material). Kinematics, cameras and tendon paths only.
    """
    import mujoco

    data.time = time
    data.qpos[:] = qpos
    data.mocap_pos[:] = mocap_pos
    data.mocap_quat[:] = mocap_quat
    if geom_rgba is not None:
        model.geom_rgba[:] = geom_rgba
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    mujoco.mj_camlight(model, data)  # cameras and lights follow their bodies
    mujoco.mj_tendon(model, data)


class _FrameRenderer:
    """One renderer that draws every camera of a frame side by side, the cut foam
    (``kerf``: the band's voxels instead of its static geoms) and the overlay text."""

    def __init__(self, model: Any, cameras: Sequence[str], width: int, height: int,
                 kerf: KerfVoxels | None = None) -> None:
        import mujoco

        self._mujoco = mujoco
        self.model = model
        self.data = mujoco.MjData(model)
        self.cameras = list(cameras)
        self.height = height
        self.kerf = kerf
        self._boxes = np.zeros((0, 6))
        self._band = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in kerf.band_geoms], int) \
            if kerf is not None else np.zeros(0, int)
        self._band = self._band[self._band >= 0]
        # Room for the scene's own geoms and the foam's boxes (at most 9 in the default run).
        self.renderer = mujoco.Renderer(model, height, width, max_geom=10000 + 2000 * (kerf is not None))

    def render_state(self, state: FrameState) -> np.ndarray:
        pose_for_drawing(self.model, self.data, state.time, state.qpos, state.mocap_pos, state.mocap_quat,
                         state.geom_rgba)
        if self.kerf is not None:
            self.model.geom_rgba[self._band, 3] = 0.0  # drawn from the voxels instead
            if state.foam is not None:
                self._boxes = self.kerf.boxes(state.foam)
        return self.render_data(self.data, state.text)

    def render_data(self, data: Any, text: tuple[str, ...] = ()) -> np.ndarray:
        tiles = []
        for name in self.cameras:
            self.renderer.update_scene(data, camera=name)
            if self.kerf is not None:
                self.kerf.add_to_scene(self.renderer.scene, self._boxes)
            tiles.append(self.renderer.render())
        frame = np.concatenate(tiles, axis=1)
        return draw_overlay(frame, text, self.height) if text else frame

    def close(self) -> None:
        self.renderer.close()


def _open_writer(path: Path, fps: float) -> Any:
    import imageio.v2 as imageio

    # "quiet": a render worker stopped by Ctrl-C (close() kills it) cuts its ffmpeg's input mid-frame,
    # and ffmpeg's complaints about the short packet (error level, and fatal when it was the
    # segment's only frame) would reach the terminal under the run's one-line message; a real
    # encoding failure still raises in the worker (imageio checks ffmpeg's exit) and reaches close().
    return imageio.get_writer(
        path, format="FFMPEG", mode="I", fps=fps, codec="libx264", quality=7, macro_block_size=8,
        ffmpeg_log_level="quiet",
    )


# ---------------------------------------------------------------- worker process side
_WORKER: dict[str, Any] = {}


def _interrupted() -> bool:
    """Whether a KeyboardInterrupt (or another non-Exception, e.g. the CLI's SIGTERM) is propagating."""
    kind = sys.exc_info()[0]
    return kind is not None and not issubclass(kind, Exception)


def _spawn_ignoring_sigint(pool: ProcessPoolExecutor, workers: int) -> None:
    """Start all render workers now with SIGINT blocked (the mask survives fork and exec): a
    terminal's Ctrl-C reaches the whole process group, and the workers must not each print a
    traceback; the driver handles it and stops them (``close``). Blocked, not ignored, in the
    driver: a Ctrl-C during the spawn stays pending and is delivered right after."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        for _ in range(workers):
            pool.submit(int)  # one spawn per submit while no worker is idle
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _worker_init(model_bytes: bytes, cameras: list[str], width: int, height: int, fps: float,
                 kerf: KerfVoxels | None = None) -> None:
    from .lifetime import die_with

    die_with()  # a SIGKILLed (or interrupted mid-start) run leaves no render worker behind
    model = pickle.loads(model_bytes)
    _WORKER["renderer"] = _FrameRenderer(model, cameras, width, height, kerf)
    _WORKER["fps"] = fps


def _worker_render(states: list[FrameState], path: str) -> int:
    """Render ``states`` into the MP4 segment ``path``; returns the frame count."""
    renderer: _FrameRenderer = _WORKER["renderer"]
    writer = _open_writer(Path(path), _WORKER["fps"])
    try:
        for state in states:
            writer.append_data(renderer.render_state(state))
    finally:
        writer.close()
    return len(states)


def concat_segments(segments: Sequence[Path], out: Path) -> None:
    """Join MP4 segments of identical encoding into ``out`` without re-encoding."""
    import imageio_ffmpeg

    if len(segments) == 1:
        os.replace(segments[0], out)
        return
    with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False, dir=out.parent) as listing:
        for segment in segments:
            listing.write(f"file '{Path(segment).resolve()}'\n")
    try:
        subprocess.run(
            [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-loglevel", "error", "-f", "concat", "-safe", "0",
             "-i", listing.name, "-c", "copy", "-f", "mp4", str(out)],
            check=True, capture_output=True,
        )
    finally:
        os.unlink(listing.name)


class VideoRecorder:
    """Capture frames at ``fps`` of simulated time from named cameras, tiled horizontally.

    ``workers`` render processes (default: the machine's cores; 0 renders in this process,
    frame by frame, inside ``maybe_capture``). Colour changes the run makes to
    ``model.geom_rgba`` (e.g. removed material) are captured with each frame.
    """

    def __init__(
        self,
        model: Any,
        path: str | os.PathLike[str],
        cameras: Sequence[str],
        width: int = 640,
        height: int = 480,
        fps: float = 25.0,
        shadows: bool = False,
        *,
        workers: int | None = None,
        quality: str = "fast",
        chunk_frames: int = 60,
        grid: Any = None,
    ) -> None:
        """``grid``: the cutter's ``FoamGrid``, whose kerf-band voxels are drawn in each frame
        instead of the band's static geoms (``video_foam``); None draws the model as it is."""
        import mujoco

        if quality not in VIDEO_SLICES:
            raise ValueError(f"video quality: must be one of {', '.join(VIDEO_SLICES)} (got {quality!r})")
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.with_name(f".{self.path.stem}.partial{self.path.suffix}")
        self.cameras = list(cameras)
        for name in self.cameras:
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name) < 0:
                raise ValueError(f"cameras: unknown camera {name!r}")
        self.model = model
        self.period = 1.0 / fps
        self.fps = fps
        self.next_time = 0.0
        self.frames = 0
        self._closed = False
        self.workers = (os.cpu_count() or 1) if workers is None else int(workers)
        self._chunk_frames = max(1, int(chunk_frames))
        self._pending: list[FrameState] = []
        self._segments: list[tuple[Path, Future[int]]] = []
        self._last_rgba: np.ndarray | None = None
        self.grid = grid
        self.kerf = None if grid is None else KerfVoxels.from_model(model, grid)
        self._last_foam: np.ndarray | None = None
        self._segment_dir: Path | None = None
        self._pool: ProcessPoolExecutor | None = None
        self._renderer: _FrameRenderer | None = None
        self._writer: Any = None
        if self.workers <= 0:
            _prepare_model(model, width, height, shadows, quality)
            self._renderer = _FrameRenderer(model, self.cameras, width, height, self.kerf)
            self._writer = _open_writer(self._tmp, fps)
        else:
            render_model = pickle.loads(pickle.dumps(model))  # the run's model stays untouched
            _prepare_model(render_model, width, height, shadows, quality)
            self._segment_dir = Path(tempfile.mkdtemp(prefix=f".{self.path.stem}.segments-", dir=self.path.parent))
            self._pool = ProcessPoolExecutor(
                max_workers=self.workers,
                mp_context=get_context("spawn"),  # a fresh process per worker: no inherited GL state
                initializer=_worker_init,
                initargs=(pickle.dumps(render_model), self.cameras, width, height, fps, self.kerf),
            )
            try:
                _spawn_ignoring_sigint(self._pool, self.workers)
            except BaseException:  # Ctrl-C delivered right after the spawn: stop the workers, then stop
                for process in list((getattr(self._pool, "_processes", None) or {}).values()):
                    process.kill()
                self._pool.shutdown(wait=False, cancel_futures=True)
                raise

    def _snapshot(self, data: Any, text: tuple[str, ...] = ()) -> FrameState:
        """The frame's state; the colour table and the kerf's voxels only when they changed or
        a new chunk starts (a worker may not have seen the previous chunk)."""
        rgba = self.model.geom_rgba
        changed = not self._pending or self._last_rgba is None or not np.array_equal(rgba, self._last_rgba)
        if changed:
            self._last_rgba = rgba.copy()
        foam = None
        if self.kerf is not None:
            packed = self.kerf.snapshot(self.grid.material)
            if not self._pending or self._last_foam is None or not np.array_equal(packed, self._last_foam):
                self._last_foam = foam = packed
        return FrameState(
            time=float(data.time),
            qpos=data.qpos.copy(),
            mocap_pos=data.mocap_pos.copy(),
            mocap_quat=data.mocap_quat.copy(),
            geom_rgba=self._last_rgba if changed else None,
            foam=foam,
            text=tuple(text),
        )

    def render_frame(self, data: Any, text: tuple[str, ...] = ()) -> np.ndarray:
        """The tiled RGB frame of the current state (in-process renderer).

        Drawn from the state copied into the renderer's own data, as the workers do: ``data``
        may belong to another model with the same state layout (the native-cable twin).
        """
        if self._renderer is None:
            raise RuntimeError("render_frame needs the in-process renderer (workers=0)")
        self._last_rgba = self._last_foam = None
        return self._renderer.render_state(self._snapshot(data, text))

    def due(self, data: Any) -> bool:
        """Whether simulated time has reached the next frame time."""
        return not self._closed and data.time + 1e-12 >= self.next_time

    def maybe_capture(self, data: Any, text: tuple[str, ...] = ()) -> bool:
        """Take a frame if simulated time has reached the next frame time; ``text``: overlay lines."""
        if not self.due(data):
            return False
        if self._writer is not None:
            self._writer.append_data(self.render_frame(data, text))
        else:
            self._pending.append(self._snapshot(data, text))
            if len(self._pending) >= self._chunk_frames:
                self._submit()
        self.frames += 1
        self.next_time += self.period
        return True

    def _submit(self) -> None:
        if not self._pending or self._pool is None or self._segment_dir is None:
            return
        states = self._pending
        path = self._segment_dir / f"segment_{len(self._segments):05d}.mp4"
        self._segments.append((path, self._pool.submit(_worker_render, states, str(path))))
        self._pending = []

    def wait_for_workers(self, report: Callable[[int], None]) -> None:
        """Block until every frame captured so far is encoded, calling ``report(frames)`` as each chunk
        finishes (a progress bar; ``close`` then only joins the segments). Nothing to wait for in-process."""
        self._submit()
        for future in as_completed([future for _, future in self._segments]):
            report(future.result())

    def close(self, keep: bool = True) -> None:
        """Finish the file; with ``keep`` it is moved to its final name, else discarded.

        Closed while Ctrl-C/SIGTERM propagates: the render workers are stopped at once and
        the partial video discarded (no half video under the final name, no wait for chunks).
        """
        if self._closed:
            return
        self._closed = True
        if _interrupted():
            keep = False
            if self._pool is not None:
                for process in list((getattr(self._pool, "_processes", None) or {}).values()):  # private: no public kill
                    process.kill()
        if self._writer is not None:
            try:
                self._writer.close()
            finally:
                if self._renderer is not None:
                    self._renderer.close()
            if keep and self.frames > 0:
                os.replace(self._tmp, self.path)
            elif self._tmp.exists():
                self._tmp.unlink()
            return
        try:
            if keep:
                self._submit()
            segments = [path for path, future in self._segments if future.result() > 0] if keep else []
            if self._pool is not None:
                self._pool.shutdown(wait=True, cancel_futures=not keep)
            if keep and segments:
                concat_segments(segments, self._tmp)
                os.replace(self._tmp, self.path)
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=False, cancel_futures=True)
            if self._segment_dir is not None:
                for leftover in self._segment_dir.glob("*"):
                    leftover.unlink()
                self._segment_dir.rmdir()
            if self._tmp.exists():
                self._tmp.unlink()

    def __enter__(self) -> VideoRecorder:
        return self

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        # A run that stopped early still keeps what was rendered (SPEC: keep what was computed).
        self.close(keep=True)

