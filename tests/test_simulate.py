"""The tick loop's bookkeeping against straightforward numpy versions of the same work:
the recorder's series, the compiled contact-force sums and the health check."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from model_helpers import contacts_on_a_plane

from continuum_sim.model.handles import GeomKind
from continuum_sim.scenario.trajectory import CONTACT_KINDS


def _reference_sums(geom: np.ndarray, normal: np.ndarray, kind: np.ndarray) -> np.ndarray:
    """The numpy version of the contact-force sums (masks and ``normal[mask].sum()``)."""
    pair = kind[geom]
    low, high = pair.min(axis=1), pair.max(axis=1)
    cutter = (low == GeomKind.CUTTER) | (high == GeomKind.CUTTER)
    gripper = ~cutter & ((low == GeomKind.GRIPPER) | (high == GeomKind.GRIPPER))
    arm_arm = (low == GeomKind.FIRST_ARM) & (high == GeomKind.SECOND_ARM)
    arm_world = (low == GeomKind.OTHER) & ((high == GeomKind.FIRST_ARM) | (high == GeomKind.SECOND_ARM))
    return np.array([normal[mask].sum() for mask in (cutter, gripper, arm_arm, arm_world)])


def test_pairwise_sum_is_numpys_sum_bit_for_bit():
    from continuum_sim.scenario import simulate

    simulate._kernels()
    rng = np.random.default_rng(3)
    for n in [*range(0, 300), 511, 1000, 1025, 4097, 20011]:
        a = np.abs(rng.standard_normal(n)) * 10.0 ** rng.uniform(-9, 9, n)
        padded = np.concatenate([a, rng.standard_normal(5)])  # only the first n count
        assert simulate._pairwise_sum(padded, n) == a.sum(), n


@pytest.mark.parametrize("n", [1, 5, 9, 40, 130, 700])
def test_contact_sums_equal_the_numpy_masks_bit_for_bit(n):
    from continuum_sim.scenario import simulate

    kernel = simulate._kernels()[0]
    rng = np.random.default_rng(n)
    kind = rng.integers(0, 5, 60).astype(np.int64)
    geom = rng.integers(0, 60, (n + 3, 2)).astype(np.int32)  # rows past n are not contacts
    address = rng.integers(-1, 4 * n, n + 3).astype(np.int32)
    efc_force = rng.standard_normal(4 * n) * 10.0 ** rng.uniform(-6, 3, 4 * n)
    out = np.full(len(CONTACT_KINDS), np.nan)
    kernel(geom, address, efc_force, simulate._NO_FORCES, kind, n, out)
    a = address[:n]
    normal = np.where(a >= 0, np.abs(efc_force[np.maximum(a, 0)]), 0.0)
    expected = _reference_sums(geom[:n], normal, kind)
    assert out.tobytes() == expected.tobytes()
    given = np.abs(rng.standard_normal(n))  # pyramidal cones: the normal forces passed in
    kernel(geom, address, efc_force, given, kind, n, out)
    assert out.tobytes() == _reference_sums(geom[:n], given, kind).tobytes()


@pytest.mark.parametrize("cone", ["elliptic", "pyramidal"])
def test_contact_forces_of_a_stepped_scene(cone):
    from continuum_sim.scenario.simulate import contact_forces, normal_forces

    model = contacts_on_a_plane(cone)
    data = mujoco.MjData(model)
    kind = np.array([GeomKind.OTHER, GeomKind.CUTTER, GeomKind.FIRST_ARM, GeomKind.GRIPPER], dtype=np.int64)
    assert contact_forces(model, data, kind).tobytes() == np.zeros(4).tobytes()  # no contacts yet
    for _ in range(100):
        mujoco.mj_step(model, data)
    n = data.ncon
    assert n >= 6
    expected = _reference_sums(data.contact.geom[:n], normal_forces(model, data, n), kind)
    assert expected[[0, 1, 3]].min() > 0.0
    assert contact_forces(model, data, kind).tobytes() == expected.tobytes()


def _sim_stub(model: mujoco.MjModel, data: mujoco.MjData):
    from types import SimpleNamespace

    return SimpleNamespace(model=model, data=data)


def test_health_check_names_a_new_warning_then_a_non_finite_state():
    from continuum_sim.scenario.simulate import HealthCheck

    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><body><freejoint/><geom size='0.1'/></body></worldbody></mujoco>")
    data = mujoco.MjData(model)
    data.warning[mujoco.mjtWarning.mjWARN_CONTACTFULL].number = 2  # counted before the run: not new
    sim = _sim_stub(model, data)
    check = HealthCheck()
    check.start(sim)  # type: ignore[arg-type]
    assert check.after_tick(sim) is None  # type: ignore[arg-type]
    for array, value in ((data.qpos, np.nan), (data.qvel, np.inf), (data.qvel, -np.inf)):
        index = len(array) - 1
        array[index] = value
        assert check.after_tick(sim) == "non-finite state at t = 0.0000 s"  # type: ignore[arg-type]
        array[index] = 0.0
    assert check.after_tick(sim) is None  # type: ignore[arg-type]
    data.qpos[0] = 1e308
    data.qvel[0] = 1e308  # finite, however large
    assert check.after_tick(sim) is None  # type: ignore[arg-type]
    data.qpos[0] = np.nan
    data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number += 1  # a warning is reported first
    assert check.after_tick(sim) == "MuJoCo warning mjWARN_BADQACC at t = 0.0000 s"  # type: ignore[arg-type]


def test_recorder_series_equal_a_per_row_gather():
    """A short default run: every recorded series equals the values read row by row, as the
    recorder did before it kept whole copies of the data arrays (keys, shapes, dtypes, bits)."""
    from continuum_sim.controllers import controller_spec, load_controller
    from continuum_sim.model.options import model_geometry
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.runner import build_scene_model, make_simulation, with_stable_step
    from continuum_sim.scenario.simulate import (
        CutterObserver,
        HealthCheck,
        Observer,
        Recorder,
        contact_forces,
        simulate,
    )
    from continuum_sim.toolpath import plan_task

    config = with_stable_step(ScenarioConfig.default())
    plan = plan_task(model_geometry(config.arm, config.model), config.layout, config.plan)
    _, model = build_scene_model(config)
    sim = make_simulation(config, plan, model, load_controller(controller_spec(config)))
    cutter = CutterObserver(sim, 3)
    recorder = Recorder(3, cutter)
    rows: dict[str, list[np.ndarray]] = {}

    class PerRow(Observer):
        def before_tick(self, sim):
            if sim.tick % 3:
                return
            data, h, i, c = sim.data, sim.handles, sim.plan_index, sim.commands

            def add(key, value):
                rows.setdefault(key, []).append(np.array(value, copy=True))

            add("t", data.time)
            add("stage", plan.stage[i])
            add("plan_index", i)
            for arm in h.arms:
                site, n_sections = h.tcp_site[arm], len(h.cable_actuators[arm]) // 3
                add(f"{arm}_q_plan", plan.q(arm)[i])
                bending = c.bending.get(arm)
                add(f"{arm}_w_cmd", np.full(2 * n_sections, np.nan) if bending is None else bending)
                add(f"{arm}_tcp_plan", plan.tcp(arm)[i])
                add(f"{arm}_tcp_pos", data.site_xpos[site])
                add(f"{arm}_tcp_mat", data.site_xmat[site].reshape(3, 3))
                add(f"{arm}_cable_length", data.ten_length[h.cable_tendons[arm]])
                add(f"{arm}_cable_tension", -data.actuator_force[h.cable_actuators[arm]])
                common = c.common_mode.get(arm)
                add(f"{arm}_cable_common_mode", np.full(n_sections, np.nan) if common is None else common)
                add(f"{arm}_disk_pos", data.xpos[h.disk_bodies[arm]])
            add("sample_pos", data.xpos[h.sample_body])
            R = data.xmat[h.plate_body].reshape(3, 3)
            add("sample_rel_pos", R.T @ (data.xpos[h.sample_body] - data.xpos[h.plate_body]))
            add("sample_welded", bool(data.eq_active[h.sample_weld]))
            add("cells_remaining", cutter.cutter.cells_remaining)
            add("spindle_speed", data.qvel[h.spindle_dof])
            add("contact_force", contact_forces(sim.model, data, h.geom_kind))

    ticks = 3 * 256 + 10  # past the first preallocation: the arrays grow once
    result = simulate(sim, ticks, [cutter, recorder, PerRow(), HealthCheck()])
    assert result.failure is None
    got = recorder.arrays()
    assert len(got["t"]) == (ticks + 2) // 3
    assert set(got) == set(rows)
    for key, values in rows.items():
        expected = np.stack(values)
        assert got[key].shape == expected.shape and got[key].dtype == expected.dtype, key
        assert got[key].tobytes() == expected.tobytes(), key


def test_recorder_without_rows_has_no_series():
    from types import SimpleNamespace

    from continuum_sim.scenario.simulate import Recorder

    recorder = Recorder(5, SimpleNamespace(cutter=None))  # type: ignore[arg-type]
    assert recorder.arrays() == {}
