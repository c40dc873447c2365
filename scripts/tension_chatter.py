"""Cable-tension chatter: the part above 10 Hz of every cable's tension, recorded every physics step.

Two reports (docs/plant.md, "Tension chatter"):

* ``hold`` (default): the gripper arm holding the welded sample (default task, 8 s to
  ``--until``) for each variant: worst cable's 10 Hz high-pass peak-to-peak, its peak
  frequency and the mean constraint-solver iterations.
* ``task``: the whole default task (or one variant) in 2 s windows, both arms, with the
  contact count (the jaw pads' contact set).

    python scripts/tension_chatter.py [hold] [--until 14] [--variants default,explicit,dt2ms] [--markdown]
    python scripts/tension_chatter.py task [--variant default]

``--markdown`` prints the hold report as the Markdown table docs/plant.md quotes (no CPU
times, so the output depends on the model only): the results pipeline's ``plant-chatter``
stage writes it to docs/results/tension_chatter_hold.md.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from continuum_sim.glbackend import choose_gl_backend

choose_gl_backend()

from scipy.signal import butter, sosfiltfilt  # noqa: E402

from continuum_sim.configio import replace_path  # noqa: E402
from continuum_sim.controllers import controller_spec, load_controller  # noqa: E402
from continuum_sim.model.options import model_geometry  # noqa: E402
from continuum_sim.scenario.cable_friction import CableFrictionObserver  # noqa: E402
from continuum_sim.scenario.config import ScenarioConfig  # noqa: E402
from continuum_sim.scenario.runner import build_scene_model, make_simulation  # noqa: E402
from continuum_sim.scenario.simulate import CutterObserver, HealthCheck, Observer, simulate  # noqa: E402
from continuum_sim.toolpath import plan_task  # noqa: E402

VARIANTS: dict[str, dict[str, Any]] = {
    "default": {},
    "dt2ms": {"model.timestep": 0.002},
    "mu0": {"model.cable_friction.mu": 0.0},
    "presliding0.2mm": {"model.cable_friction.presliding": 0.0002},
    "pad_friction0.5": {"scene.tools.pad_friction": 0.5},
    "motor_kp10": {"model.motor_kp": 10.0, "model.motor_ki": 25.0},
    "explicit": {"model.cable_implicit_spring": False},
    "explicit_mu0": {"model.cable_implicit_spring": False, "model.cable_friction.mu": 0.0},
    "explicit_tick250": {"model.cable_implicit_spring": False, "control.rate_hz": 250.0},
    "explicit_kp10": {"model.cable_implicit_spring": False, "model.motor_kp": 10.0, "model.motor_ki": 25.0},
    "explicit_dt2.67ms": {"model.cable_implicit_spring": False, "model.timestep": 0.008 / 3},
    "explicit_dt2ms": {"model.cable_implicit_spring": False, "model.timestep": 0.002},
    "explicit_damping400": {"model.cable_implicit_spring": False, "model.cable_damping": 400.0},
    "explicit_modulus0.5": {"model.cable_implicit_spring": False, "model.rope_modulus": 36.6e9},
    "lumped_explicit": {"model.cable_model": "lumped", "model.cable_implicit_spring": False},
    "lumped": {"model.cable_model": "lumped"},
}


class _PerStep(Observer):
    """Every physics step: time, solver iterations, contacts, stage, both arms' cable tensions."""

    def __init__(self, until: float) -> None:
        self.until = until
        self.rows: list[np.ndarray] = []

    def after_physics_step(self, sim: Any) -> None:
        d, h = sim.data, sim.handles
        head = [d.time, d.solver_niter[0], d.ncon, sim.plan.stage[sim.plan_index]]
        self.rows.append(np.concatenate([head, *(-d.actuator_force[h.cable_actuators[a]] for a in h.arms)]))

    def after_tick(self, sim: Any) -> str | None:
        return "end of window" if sim.data.time >= self.until else None


def record(overrides: dict[str, Any], until: float) -> tuple[np.ndarray, list[str], float, float]:
    """Per-step rows of the default task with ``overrides``, up to ``until`` s (at most the plan's
    end); arms, step rate, CPU s."""
    config = ScenarioConfig.default()
    for path, value in overrides.items():
        config = replace_path(config, path, value)
    start = time.process_time()
    plan = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    _, model = build_scene_model(config)
    sim = make_simulation(config, plan, model, load_controller(controller_spec(config)))
    steps = _PerStep(until)
    hooks = [CutterObserver(sim), CableFrictionObserver(config.model.cable_friction, 1), steps, HealthCheck()]
    until = min(until, float(plan.t[-1]))  # the whole task at most
    simulate(sim, int(np.ceil(until / sim.control_period)) + 1, hooks)
    return np.array(steps.rows), list(sim.handles.arms), 1.0 / sim.timestep, time.process_time() - start


def high_pass(x: np.ndarray, rate: float) -> np.ndarray:
    return sosfiltfilt(butter(4, 10.0, "highpass", fs=rate, output="sos"), x, axis=0)


def _overrides(name: str) -> str:
    changes = VARIANTS[name]
    if not changes:
        return "shipped defaults"
    return ", ".join(f"`{path} = {str(value).lower() if isinstance(value, bool) else format(value, '.4g') if isinstance(value, float) else value}`"
                     for path, value in changes.items())


def hold_report(variants: list[str], until: float, markdown: bool = False) -> None:
    if markdown:
        print("| variant | changed from the defaults | p-p above 10 Hz (N) | peak (Hz) | solver iterations |")
        print("|---|---|---|---|---|")
    else:
        print(f"gripper arm holding the welded sample, 8-{until:g} s, per physics step")
        print(f"{'variant':22s} {'p-p >10 Hz (N)':>15s} {'peak (Hz)':>10s} {'iterations':>11s} {'CPU s':>6s}")
    for name in variants:
        rows, arms, rate, cpu = record(VARIANTS[name], until)
        n = (rows.shape[1] - 4) // len(arms)
        gripper = 4 + n * arms.index("right")
        window = rows[:, 0] >= 8.0
        tension = rows[window, gripper:gripper + n]
        high = high_pass(tension, rate)[25:-25]
        worst = int(np.argmax(np.ptp(high, axis=0)))
        spectrum = np.abs(np.fft.rfft(high[:, worst]))
        peak = np.fft.rfftfreq(len(high), 1.0 / rate)[np.argmax(spectrum)]
        p2p = float(np.ptp(high, axis=0).max())
        if markdown:
            print(f"| {name} | {_overrides(name)} | {p2p:.1f} | {f'{peak:.0f}' if p2p > 0.5 else '–'} "
                  f"| {rows[window, 1].mean():.1f} |", flush=True)
            continue
        shown = f"{peak:10.1f}" if p2p > 0.5 else f"{'-':>10s}"
        print(f"{name:22s} {p2p:15.2f} {shown} {rows[window, 1].mean():11.2f} {cpu:6.1f}", flush=True)


def task_report(variant: str) -> None:
    rows, arms, rate, cpu = record(VARIANTS[variant], np.inf)
    n = (rows.shape[1] - 4) // len(arms)
    high = high_pass(rows[:, 4:], rate)
    t = rows[:, 0]
    print(f"whole task ({variant}), worst cable's 10 Hz high-pass p-p per 2 s window; CPU {cpu:.1f} s")
    print("window      " + "  ".join(f"{a:>8s}" for a in arms) + "  iterations  contacts  stage")
    for t0 in np.arange(0.0, t[-1], 2.0):
        s = (t >= t0) & (t < t0 + 2.0)
        p2p = [np.ptp(high[s, i * n:(i + 1) * n], axis=0).max() for i in range(len(arms))]
        contacts = rows[s, 2]
        print(f"{t0:4.0f}-{t0 + 2:<4.0f}  " + "  ".join(f"{x:8.2f}" for x in p2p)
              + f"  {rows[s, 1].mean():10.1f}  {contacts.min():3.0f}-{contacts.max():<3.0f}   {int(np.median(rows[s, 3]))}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", nargs="?", default="hold", choices=("hold", "task"))
    parser.add_argument("--until", type=float, default=14.0, help="hold: end of the window (s)")
    parser.add_argument("--variants", default="default,explicit", help=f"hold: comma-separated, of {', '.join(VARIANTS)}")
    parser.add_argument("--variant", default="default", help="task: one variant")
    parser.add_argument("--markdown", action="store_true", help="hold: print the Markdown table docs/plant.md quotes")
    args = parser.parse_args()
    if args.report == "hold":
        names = [v.strip() for v in args.variants.split(",") if v.strip()]
        unknown = [v for v in names if v not in VARIANTS]
        if unknown:
            parser.error(f"--variants: unknown {', '.join(unknown)} (allowed: {', '.join(VARIANTS)})")
        hold_report(names, args.until, args.markdown)
    else:
        if args.variant not in VARIANTS:
            parser.error(f"--variant: unknown {args.variant} (allowed: {', '.join(VARIANTS)})")
        task_report(args.variant)


if __name__ == "__main__":
    main()
