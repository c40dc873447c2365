"""The compiled cutter (``FoamOptions.native``, model/cutting_kernels.py) against the numpy
path: bit-identical per physics step on a cutting rig, and identical task metrics of the
default run."""

import dataclasses
import math

import mujoco
import numpy as np
import pytest
from test_cutting import OFFSET, SPEED, cut_path, make

from continuum_sim.configio import ConfigError
from continuum_sim.model import cutting_kernels as ck
from continuum_sim.model.cutting import CutState, FoamOptions
from continuum_sim.model.scene import SceneOptions
from continuum_sim.model.tools import ToolOptions

STATE_FIELDS = [f.name for f in dataclasses.fields(CutState)]


def _rig(native: bool, tools: ToolOptions | None = None):
    return make(SceneOptions(foam=FoamOptions(native=native), tools=tools or ToolOptions()))


def _lockstep(tools: ToolOptions | None = None, spindle=lambda t: SPEED, feed=0.04, jitter=(0.0008, 7.0), until=None,
              sums=False):
    """Both paths driven along the L cut (with back-and-forth jitter, which exercises the
    recent-centres exclusion); asserts every step's CutState, the grid and the MuJoCo state equal.
    With ``sums`` each step is ``FoamCutter.tick`` (the observer's hook: the native cutter's
    one fused call) into sums reset every other step, as the observer's per tick; the sums,
    the spindle loop's state and events and the set-point must be equal too."""
    rigs = [_rig(True, tools), _rig(False, tools)]
    points = cut_path()
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    duration = 0.5 + cum[-1] / feed if until is None else until

    def at(s):
        s = float(np.clip(s, 0.0, cum[-1]))
        i = min(int(np.searchsorted(cum, s, side="right")) - 1, len(points) - 2)
        return points[i] + (s - cum[i]) / (cum[i + 1] - cum[i]) * (points[i + 1] - points[i])

    for model, data, _ in rigs:
        free = model.jnt_qposadr[model.body("left/").jntadr[0]]
        data.mocap_pos[model.body("left_target").mocapid[0]] = data.qpos[free:free + 3] = points[0] - OFFSET
        mujoco.mj_forward(model, data)
    counts = {"steps": 0, "feeding": 0, "removing": 0, "blocked": 0, "checks": 0, "far": 0, "fused": 0, "python": 0}
    (m1, d1, c1), (m2, d2, c2) = rigs
    assert c1._fv is not None and c2._fv is None  # the native cutter runs the fused step
    fused = c1._native_tick

    def counted(*args):
        flags = fused(*args)
        counts[("far", "fused", "python")[int(c1._fv[ck.F_OUTCOME])]] += 1
        return flags

    c1._native_tick = counted
    accs = [np.zeros(ck.N_A), np.zeros(ck.N_A)]
    while d1.time < duration:
        s = feed * max(d1.time - 0.5, 0.0) + jitter[0] * math.sin(2 * math.pi * jitter[1] * d1.time)
        states = []
        for (model, data, cutter), acc in zip(rigs, accs, strict=True):
            data.mocap_pos[model.body("left_target").mocapid[0]] = at(s) - OFFSET
            if sums:
                if counts["steps"] % 2 == 0:
                    acc[:] = 0.0
                cutter.tick(spindle(data.time), acc)
                states.append(cutter.state)
            else:
                states.append(cutter.step(spindle(data.time)))
            mujoco.mj_step(model, data)
            cutter.after_step()
        a, b = states
        if sums:
            assert np.array_equal(accs[0], accs[1]), (d1.time, accs)
            assert np.array_equal(d1.ctrl, d2.ctrl), d1.time
            for name in ("integral", "stalled", "low_since", "events"):
                assert getattr(c1.spindle, name) == getattr(c2.spindle, name), (d1.time, name)
        for name in STATE_FIELDS:
            assert np.array_equal(getattr(a, name), getattr(b, name)), (d1.time, name, getattr(a, name), getattr(b, name))
        assert c1.removed_volume == c2.removed_volume and c1.detach_time == c2.detach_time
        assert c1.cells_remaining == c2.cells_remaining
        assert np.array_equal(d1.qpos, d2.qpos) and np.array_equal(d1.qvel, d2.qvel), d1.time
        if states[0].feed_speed and states[0].depth > 0:
            counts["feeding"] += 1
        counts["removing"] += c1.removed_volume > 0 and states[0].cutting
        counts["blocked"] += states[0].blocked
        counts["steps"] += 1
    g1, g2 = c1.grid, c2.grid
    assert np.array_equal(g1.material, g2.material) and np.array_equal(g1.cut, g2.cut)
    assert np.array_equal(g1.removed_at, g2.removed_at, equal_nan=True)
    assert c1.checks == c2.checks and c1.detached == c2.detached
    counts["checks"] = c1.checks
    return counts, c1


def test_native_cutter_equals_numpy_per_step_through_the_whole_cut():
    """The L cut to detachment: engagement, force, removal, recent-centres exclusion."""
    counts, cutter = _lockstep()
    assert counts["feeding"] > 500 and counts["removing"] > 500
    assert counts["fused"] > 500 and counts["far"] > 0
    assert cutter.detached and cutter.cells_remaining == 0


def test_native_cutter_equals_numpy_when_blocked():
    """Spindle off while the cutter is pressed in (the block spring), then on again."""
    counts, cutter = _lockstep(spindle=lambda t: SPEED if t < 0.9 or t > 1.3 else 0.0, until=1.6)
    assert counts["blocked"] > 10 and counts["removing"] > 10
    assert counts["python"] >= counts["blocked"] and counts["fused"] > 10  # (the block spring is Python's)


def test_fused_tick_equals_python_through_a_stall_and_its_recovery():
    """The observer's hook (``FoamCutter.tick``): one compiled call natively (spindle loop,
    step, sums) against the Python path. It cuts; a command beyond the spindle's top speed
    trips the stall (the stalled cutter pressed into the foam: the block spring); the command
    off re-arms it; the command back spins it up and it cuts again."""
    over = 3.0 * ToolOptions().spindle_max_speed  # unreachable: speed < stall fraction × command

    def command(t):
        return SPEED if t < 0.8 else over if t < 1.4 else 0.0 if t < 1.45 else SPEED

    counts, cutter = _lockstep(spindle=command, until=2.2, sums=True)
    events = cutter.spindle.events
    assert len(events) == 1 and events[0][1] == "stall" and 1.29 < events[0][0] < 1.4
    assert not cutter.stalled and cutter.spindle.integral != 0.0 and cutter.spindle_speed == pytest.approx(SPEED, rel=0.05)
    assert counts["blocked"] > 10 and counts["python"] >= counts["blocked"]
    # (feeding from 0.5 s: at most 800 steps before the stall, so it cut after the recovery too)
    assert counts["fused"] > 1000 and counts["far"] > 0 and counts["feeding"] > 1000


def test_spindle_loop_state_is_a_view_of_the_fused_step():
    """The native cutter's SpindleLoop reads and writes the fused step's slots: a reset or
    a Python ``control`` call there is what the kernel sees next."""
    _, _, cutter = _rig(True)
    spindle = cutter.spindle
    assert np.shares_memory(spindle.state, cutter._fv)
    spindle.integral, spindle.low_since, spindle.stalled = 1e-3, 0.25, True
    assert cutter._fv[ck.F_SP:ck.F_SP + 4].tolist() == [1e-3, 1.0, 1.0, 0.25]
    spindle.reset()
    assert (spindle.integral, spindle.stalled, spindle.low_since) == (0.0, False, None)


def test_fused_step_hypot_equals_math_hypot():
    """The fused step's feed speed: CPython's correctly rounded ``math.hypot`` (libm's, which
    numba's ``math.hypot`` calls, differs in the last bit in about 1 of 1000 cases)."""
    from continuum_sim.model.cutting_kernels import kernels

    hypot = kernels()["hypot"]
    rng = np.random.default_rng(7)
    x = rng.standard_normal(20000) * 10.0 ** rng.integers(-12, 3, 20000)
    y = rng.standard_normal(20000) * 10.0 ** rng.integers(-12, 3, 20000)
    special = [0.0, -0.0, 5e-324, 1e-310, 2.2250738585072014e-308, 1e300, math.inf, -math.inf, math.nan, 3.0, -4.0]
    pairs = [*zip(x.tolist(), y.tolist(), strict=True), *((a, b) for a in special for b in special)]
    for a, b in pairs:
        got, want = hypot(a, b), math.hypot(a, b)
        assert got == want or (math.isnan(got) and math.isnan(want)), (a, b, got, want)


def test_native_option_validates():
    assert FoamOptions().native is True
    with pytest.raises(ConfigError, match="native"):
        FoamOptions(native=1)  # type: ignore[arg-type]


def test_default_task_metrics_equal_between_the_paths():
    """The whole default run (it mills, detaches and carries the sample) with either path."""
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.metrics import WALL_CLOCK_METRICS
    from continuum_sim.scenario.runner import run_scenario

    config = ScenarioConfig.default()
    assert config.scene.foam.native
    python = dataclasses.replace(config, scene=dataclasses.replace(
        config.scene, foam=dataclasses.replace(config.scene.foam, native=False)))
    native_metrics, python_metrics = (
        {k: v for k, v in run_scenario(c, None).items() if k not in WALL_CLOCK_METRICS} for c in (config, python))
    assert native_metrics["task"]["completed"]
    assert native_metrics == python_metrics  # bit-identical: == on every float


def _labelled(material, held_columns):
    """The numpy path's answer (``FoamCutter.check_connectivity``): (-1 no held material /
    1 anchored / 0 loose, the loose voxels)."""
    from scipy import ndimage

    labels, _ = ndimage.label(material)
    anchored = np.unique(labels[0])
    anchored = anchored[anchored > 0]
    held = labels[held_columns]
    held = held[held > 0]
    loose = (labels > 0) & ~np.isin(labels, anchored)
    if held.size == 0:
        return -1, loose
    return int(np.isin(held, anchored).any()), loose


@pytest.mark.parametrize("fill", [0.3, 0.45, 0.6, 0.9])
def test_native_connectivity_equals_labelling_on_random_grids(fill):
    """The flood fill (early exit at the anchor face) against ``scipy.ndimage.label``: the same
    verdict and the same freed voxels, around the percolation threshold and above."""
    from continuum_sim.model.cutting_kernels import kernels

    k = kernels()
    rng = np.random.default_rng(int(fill * 100))
    outcomes = set()
    for _ in range(60):
        shape = tuple(int(n) for n in rng.integers(1, 9, size=3))
        material = rng.random(shape) < fill
        held_columns = rng.random(shape[:2]) < 0.2
        held_columns[rng.integers(shape[0]), rng.integers(shape[1])] = True
        verdict, loose = _labelled(material, held_columns)
        assert k["held_anchored"](material, np.flatnonzero(held_columns).astype(np.int64)) == verdict
        outcomes.add(verdict)
        freed = material.copy()
        assert k["free_loose"](freed) == np.count_nonzero(loose)
        assert np.array_equal(freed, material & ~loose)
    assert len(outcomes) >= 2 or fill > 0.8  # (a dense grid is always anchored)


def test_native_connectivity_on_a_cut_plate():
    """A slab cut through except a one-voxel bridge: anchored until the bridge goes, then the
    far part is freed (both paths)."""
    from continuum_sim.model.cutting_kernels import kernels

    k = kernels()
    material = np.ones((40, 30, 5), bool)
    material[20, :, :] = False
    material[20, 29, 4] = True  # the bridge
    held = np.zeros((40, 30), bool)
    held[35, 10] = True
    flat = np.flatnonzero(held).astype(np.int64)
    assert k["held_anchored"](material, flat) == _labelled(material, held)[0] == 1
    material[20, 29, 4] = False
    assert k["held_anchored"](material, flat) == _labelled(material, held)[0] == 0
    freed = material.copy()
    assert k["free_loose"](freed) == 19 * 30 * 5
    assert np.array_equal(freed, material & ~_labelled(material, held)[1])
    material[:, 10, :] = False  # no material under the jaws
    assert k["held_anchored"](material, flat) == _labelled(material, held)[0] == -1


def test_without_mujocos_library_by_path_the_cutter_takes_its_python_step(monkeypatch: pytest.MonkeyPatch) -> None:
    """The fused step calls mj_jac/mj_solveM by address; where the library is not found next to
    the bindings (``mujoco_native.mujoco_symbols`` None) the cutter runs its Python step, the same numbers."""
    from continuum_sim.plant import mujoco_native

    assert ck.mujoco_functions() is not None  # here it is found
    monkeypatch.setattr(mujoco_native, "mujoco_symbols", lambda *names: None)
    assert ck.mujoco_functions() is None
    model, data, cutter = _rig(True)
    assert cutter._native_tick is None and cutter._fv is None
    reference_model, reference_data, reference = _rig(False)
    for _ in range(50):
        for m, d, c in ((model, data, cutter), (reference_model, reference_data, reference)):
            c.step(SPEED)
            mujoco.mj_step(m, d)
    np.testing.assert_array_equal(data.qvel, reference_data.qvel)
    assert cutter.spindle.integral == reference.spindle.integral
