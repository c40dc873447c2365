"""Replay a recording through the model and compare predicted with measured tool poses.

Two ways to drive the model (``RecordingInfo.mode``):

* ``dynamic``: the arm first settles at the first command for ``settle_s``, then every
  physics step gets the command interpolated at its time; predicted poses are read at
  the recording's times (linear interpolation between steps);
* ``quasi_static``: every row's command is held for ``settle_s`` and the pose is read at
  the end (a robot stepped slowly from pose to pose, as motion-capture sysid data is).

Both run in C with ``mujoco.rollout`` in chunks; several parameter variants of the same
model structure (an identification's Jacobian columns) run in one call on ``nthread``
threads.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout
from numpy.typing import NDArray

from ..configio import atomic_write_bytes, atomic_write_text
from ..scenario.config import ScenarioConfig
from ..scenario.trajectory import npz_bytes
from .data import Recording
from .plant import ReplayModel, build_replay_model, control_matrix

Array = NDArray[np.float64]
FULL = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
CHUNK_STEPS = 4000


@dataclass
class Prediction:
    """Model output at every row of the recording (NaN where the simulation diverged)."""

    position: Array  # (N, 3) m
    quaternion: Array  # (N, 4)
    tension: Array  # (N, ncables) N


def _friction_of(config: ScenarioConfig):
    """The config's cable friction when it acts (μ > 0), else None (plant/friction.py)."""
    friction = getattr(config.model, "cable_friction", None)
    return friction if friction is not None and friction.mu > 0.0 else None


def _rollout_sampled(plants: list[ReplayModel], controls: list[Array], sample_steps: NDArray[np.int_],
                     nthread: int, friction=None) -> list[Array]:
    """Roll every model out under its control rows (nstep, nu); sensordata at ``sample_steps``.

    ``friction``: cable friction installed on the (single) rollout data, whose stick/slip
    state then carries over the chunks (one model per call).
    """
    models = [p.model for p in plants]
    nstep = controls[0].shape[0]
    datas = [mujoco.MjData(models[0]) for _ in range(max(1, min(nthread, len(models))))]
    handle = None
    if friction is not None:
        from ..plant.friction import install_cable_friction

        if len(models) != 1:
            raise ValueError("cable friction: one model per rollout call")
        datas = datas[:1]
        handle = install_cable_friction(models[0], datas[0], friction)
    try:
        return _rollout_chunks(models, datas, controls, sample_steps, nstep)
    finally:
        if handle is not None:
            handle.uninstall()
            handle.check()


def _rollout_chunks(models, datas, controls, sample_steps, nstep) -> list[Array]:
    state = np.empty((len(models), mujoco.mj_stateSize(models[0], FULL)))
    for i, m in enumerate(models):
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        mujoco.mj_getState(m, d, state[i], FULL)
    ns = models[0].nsensordata
    out = [np.full((len(sample_steps), ns), np.nan) for _ in models]
    ctrl = np.stack(controls)
    for start in range(0, nstep, CHUNK_STEPS):
        stop = min(nstep, start + CHUNK_STEPS)
        states, sens = rollout.rollout(models, datas, state, ctrl[:, start:stop, :])
        sel = (sample_steps >= start) & (sample_steps < stop)
        for i in range(len(models)):
            out[i][sel] = sens[i, sample_steps[sel] - start]
        state = np.ascontiguousarray(states[:, -1, :])
        if not np.all(np.isfinite(state)):
            bad = ~np.all(np.isfinite(state), axis=1)
            for i in np.flatnonzero(bad):  # type: ignore[assignment]
                out[i][sample_steps >= start] = np.nan
            state[bad] = 0.0
    return out


def _same_structure(models: list[mujoco.MjModel]) -> bool:
    keys = {(m.nq, m.nv, m.nu, m.na, m.nsensordata, m.nbody, m.njnt) for m in models}
    return len(keys) == 1


def marker_point(pred: Prediction, offset) -> Prediction:
    """The prediction at the measured point: tool centre + R(q)·offset (``arm.tools.marker_offset``)."""
    off = np.asarray(offset, dtype=float)
    if not np.any(off):
        return pred
    w, v = pred.quaternion[:, :1], pred.quaternion[:, 1:]
    t = 2.0 * np.cross(v, np.broadcast_to(off, v.shape))
    rotated = off + w * t + np.cross(v, t)  # R(q)·off for unit q = (w, v)
    return Prediction(pred.position + rotated, pred.quaternion, pred.tension)


def _simulate_one(args: tuple[ScenarioConfig, Recording]) -> Prediction:
    config, rec = args
    return simulate([config], rec, 1, marker=False)[0]


_POOL: dict[int, Any] = {}


def _process_pool(workers: int):
    """A pool of ``workers`` processes kept for the session (forked: no re-import, warm kernels)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    if workers not in _POOL:
        _POOL[workers] = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"))
    return _POOL[workers]


def simulate(configs: list[ScenarioConfig], rec: Recording, nthread: int = 1,
             plants: list[ReplayModel] | None = None, marker: bool = True) -> list[Prediction]:
    """Replay ``rec`` through the model of every config; one prediction per config.

    ``marker``: predictions at the configs' measured point (``arm.tools.marker_offset``);
    False gives the tool centre. Variants with cable friction (its stick/slip state lives
    per MuJoCo data) run one per process on ``nthread`` processes.
    """
    if marker:
        raw = simulate(configs, rec, nthread, plants, marker=False)
        return [marker_point(p, c.arm.tools.marker_offset) for p, c in zip(raw, configs)]
    info = rec.info
    frictions = [_friction_of(c) for c in configs]
    if len(configs) > 1 and nthread > 1 and plants is None and any(f is not None for f in frictions):
        pool = _process_pool(min(nthread, len(configs)))
        return list(pool.map(_simulate_one, [(c, rec) for c in configs]))
    if plants is None:
        plants = [build_replay_model(c, rec.arm, info.tool, info.gravity) for c in configs]
    if len(configs) > 1 and (any(f is not None for f in frictions) or not _same_structure([p.model for p in plants])):
        # Friction keeps its stick/slip state per MuJoCo data: one rollout per variant.
        return [simulate([c], rec, 1, [p], marker=False)[0] for c, p in zip(configs, plants)]
    friction = frictions[0]
    dt = plants[0].model.opt.timestep
    settle = max(1, round(info.settle_s / dt))
    n = len(rec.time)
    if info.mode == "dynamic":
        t0 = rec.time[0]
        steps = int(np.ceil((rec.time[-1] - t0) / dt)) + 2
        times = t0 + dt * np.arange(steps)
        delta = np.stack([np.interp(times, rec.time, rec.commands[:, j]) for j in range(rec.n_cables)], axis=1)
        grip = None if rec.gripper is None else np.interp(times, rec.time, rec.gripper)
        spin = None if rec.spindle is None else np.interp(times, rec.time, rec.spindle)
        first = slice(0, 1)
        controls = []
        for c, p in zip(configs, plants):
            pre = control_matrix(c, p, rec.commands[first], None if grip is None else grip[first],
                                 None if spin is None else spin[first])
            run = control_matrix(c, p, delta, grip, spin)
            controls.append(np.concatenate([np.repeat(pre, settle, axis=0), run]))
        sample = settle + np.arange(steps)
        sens = _rollout_sampled(plants, controls, sample, nthread, friction)
        out = []
        for s in sens:
            pos = np.stack([np.interp(rec.time, times, s[:, j]) for j in range(3)], axis=1)
            idx = np.clip(np.round((rec.time - t0) / dt).astype(int), 0, steps - 1)
            quat = s[idx, 3:7]
            tension = -np.stack([np.interp(rec.time, times, s[:, 7 + j]) for j in range(rec.n_cables)], axis=1)
            out.append(Prediction(pos, quat, tension + 0.0))
        return out
    controls = []
    for c, p in zip(configs, plants):
        rows = control_matrix(c, p, rec.commands, rec.gripper, rec.spindle)
        controls.append(np.repeat(rows, settle, axis=0))
    sample = settle * np.arange(1, n + 1) - 1
    sens = _rollout_sampled(plants, controls, sample, nthread, friction)
    return [Prediction(s[:, 0:3].copy(), s[:, 3:7].copy(), -s[:, 7:7 + rec.n_cables] + 0.0) for s in sens]


# ----------------------------------------------------------------------------- errors
def quaternion_angle_deg(q_a: Array, q_b: Array) -> Array:
    """Rotation angle between unit quaternions (deg), row by row."""
    dot = np.abs(np.sum(q_a * q_b, axis=1))
    return np.degrees(2.0 * np.arccos(np.clip(dot, 0.0, 1.0)))


def position_errors(pred: Prediction, rec: Recording) -> Array:
    """(M, 3) predicted − measured at the measured rows (m), mean removed when ``align = offset``."""
    rows = rec.measured
    err = pred.position[rows] - rec.position[rows]
    if rec.info.align == "offset":
        err = err - np.nanmean(err, axis=0)
    return err


def _stats(values: Array) -> dict[str, float]:
    if values.size == 0 or not np.all(np.isfinite(values)):
        return {"mean": float("nan"), "rms": float("nan"), "max": float("nan")}
    return {"mean": float(np.mean(values)), "rms": float(np.sqrt(np.mean(values**2))), "max": float(np.max(values))}


def replay_metrics(pred: Prediction, rec: Recording) -> dict[str, Any]:
    """Position (mm) and orientation (deg) error statistics over the measured rows."""
    rows = rec.measured
    raw = np.linalg.norm(pred.position[rows] - rec.position[rows], axis=1) * 1000.0
    aligned = np.linalg.norm(position_errors(pred, rec), axis=1) * 1000.0
    out: dict[str, Any] = {
        "samples": int(rows.sum()),
        "align": rec.info.align,
        "position_error_mm": _stats(aligned),
        "position_error_unaligned_mm": _stats(raw),
        "diverged": bool(not np.all(np.isfinite(pred.position[rows]))),
    }
    if rec.info.align == "offset":
        out["mean_offset_mm"] = (1000.0 * np.nanmean(pred.position[rows] - rec.position[rows], axis=0)).tolist()
    if rec.quaternion is not None:
        out["orientation_error_deg"] = _stats(quaternion_angle_deg(pred.quaternion[rows], rec.quaternion[rows]))
    if rec.tensions is not None:
        out["tension_error_n"] = _stats(np.abs(pred.tension[rows] - rec.tensions[rows]).ravel())
    return out


# ------------------------------------------------------------------------- run folder
def plot_paths(rec: Recording, preds: dict[str, Prediction], path: Path, title: str) -> None:
    """Measured vs predicted tool paths (three projections) and position error over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..configio import atomic_write_figure

    rows = rec.measured
    meas = rec.position[rows] * 1000.0
    t = rec.time[rows] - rec.time[0]
    fig, axes = plt.subplots(2, 2, figsize=(11, 9))
    for ax, (i, j) in zip(axes.ravel()[:3], ((0, 1), (0, 2), (1, 2))):
        ax.plot(meas[:, i], meas[:, j], ".", ms=2.5, color="k", label="measured")
        for (name, p), color in zip(preds.items(), ("tab:red", "tab:blue", "tab:green")):
            q = p.position[rows] * 1000.0
            if rec.info.align == "offset":
                q = q - np.nanmean(q - meas, axis=0)
            ax.plot(q[:, i], q[:, j], "-", lw=0.8, color=color, label=name)
        ax.set_xlabel("xyz"[i] + " [mm]")
        ax.set_ylabel("xyz"[j] + " [mm]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    ax = axes[1, 1]
    for (name, p), color in zip(preds.items(), ("tab:red", "tab:blue", "tab:green")):
        err = np.linalg.norm(position_errors(p, rec), axis=1) * 1000.0
        ax.plot(t, err, lw=0.8, color=color, label=name)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("position error [mm]" + (" (mean offset removed)" if rec.info.align == "offset" else ""))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.suptitle(title)
    atomic_write_figure(fig, path)


def write_replay_folder(out: Path, config: ScenarioConfig, rec: Recording, pred: Prediction, metrics: dict[str, Any],
                        label: str = "replayed") -> None:
    """A run folder: resolved config, metrics, time series, plots (like ``run``'s)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "plots").mkdir(exist_ok=True)
    config.save_toml(out / "config.toml")
    atomic_write_text(out / "replay.json", json.dumps(metrics, indent=2))
    rows = rec.measured
    err = np.full(len(rec.time), np.nan)
    err[rows] = np.linalg.norm(position_errors(pred, rec), axis=1)
    arrays: dict[str, Any] = {
        "time": rec.time, "commands": rec.commands, "measured_position": rec.position,
        "predicted_position": pred.position, "predicted_quaternion": pred.quaternion,
        "predicted_tension": pred.tension, "position_error": err,
    }
    if rec.quaternion is not None:
        arrays["measured_quaternion"] = rec.quaternion
        ang = np.full(len(rec.time), np.nan)
        ang[rows] = quaternion_angle_deg(pred.quaternion[rows], rec.quaternion[rows])
        arrays["orientation_error_deg"] = ang
    atomic_write_bytes(out / "trajectory.npz", npz_bytes(arrays))  # no entry dates: same replay, same bytes
    e = metrics["position_error_mm"]
    robot = rec.info.source.split(" (")[0] if rec.info.source else f"{rec.arm} arm"  # an imported robot by its own name
    plot_paths(rec, {label: pred}, out / "plots" / "tool_paths.png",
               f"{robot} replay: position error mean {e['mean']:.3g} / RMS {e['rms']:.3g} / max {e['max']:.3g} mm")


def run_replay(config: ScenarioConfig, rec: Recording, out: str | os.PathLike[str]) -> dict[str, Any]:
    """``continuum-sim replay``: simulate, compare, write the run folder; returns the metrics."""
    import time

    t0 = time.process_time()
    plant = build_replay_model(config, rec.arm, rec.info.tool, rec.info.gravity)
    (pred,) = simulate([config], rec, 1, [plant])
    metrics = replay_metrics(pred, rec)
    metrics["mode"] = rec.info.mode
    metrics["tool"] = plant.tool
    metrics["gravity"] = rec.info.gravity
    metrics["cpu_s"] = time.process_time() - t0
    write_replay_folder(Path(out), config, rec, pred, metrics)
    return metrics
