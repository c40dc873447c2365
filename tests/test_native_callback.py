"""The one passive callback (``plant/passive.py``): per-data runtimes, the dispatch table, the public-API fallback."""

from __future__ import annotations

import gc

import mujoco
import numpy as np
import pytest
from test_cable_path import _arm_root, _drive

from continuum_sim.model.friction_options import CableFrictionConfig
from continuum_sim.plant import cable_kernels, mujoco_native, passive
from continuum_sim.plant import cable_path as cp
from continuum_sim.plant import friction as fr


def _slot(data: mujoco.MjData) -> int | None:
    found = np.flatnonzero(passive._DISPATCH.table[0]["data"] == data._address)
    return int(found[0]) if found.size else None


def _run(native: mujoco.MjModel) -> np.ndarray:
    data = cp.make_data(native)
    handle = fr.install_cable_friction(native, data, CableFrictionConfig())
    state = _drive(native, data, 150, seed=3)
    handle.check()
    out = np.r_[state, data.qfrc_passive, data.ten_J, data.actuator_moment, handle.z, handle.piece_tension]
    cp.release_data(data)
    return out


@pytest.fixture
def fallback(monkeypatch: pytest.MonkeyPatch) -> None:
    """The process as where MuJoCo's library is not found by path: the Python callback is built instead."""
    assert not passive._DISPATCH.runtimes or all(not r.active for r in passive._DISPATCH.runtimes.values())
    monkeypatch.setattr(mujoco_native, "mujoco_symbols", lambda *names: None)
    monkeypatch.setattr(passive._DISPATCH, "callback", None)
    monkeypatch.setattr(passive._DISPATCH, "fallback", False)
    yield
    assert mujoco.get_mjcb_passive() is None  # the test released its datas


def test_the_public_api_fallback_gives_the_compiled_callbacks_numbers(monkeypatch: pytest.MonkeyPatch) -> None:
    """Both call the same compiled kernels on the same record; only ``mj_fwdActuation`` is called
    through MuJoCo's Python API instead of by address: 150 steps with friction agree to 1e-12."""
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    compiled = _run(native)
    assert not passive._DISPATCH.fallback
    monkeypatch.setattr(mujoco_native, "mujoco_symbols", lambda *names: None)
    monkeypatch.setattr(passive._DISPATCH, "callback", None)
    python = _run(native)
    assert passive._DISPATCH.fallback and isinstance(passive.installed_callback(), passive.ctypes._CFuncPtr)
    np.testing.assert_allclose(python, compiled, rtol=1e-12, atol=1e-12)
    assert np.ptp(compiled) > 0
    assert mujoco.get_mjcb_passive() is None  # nothing registered: the callback is handed back
    monkeypatch.undo()
    passive._DISPATCH.fallback = False


def test_every_declared_array_is_bound_for_a_native_data_with_friction() -> None:
    """The record's one declaration (``cable_kernels.ARRAYS``) and what the hooks bind agree."""
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    data = cp.make_data(native)
    fr.install_cable_friction(native, data, CableFrictionConfig())
    row = passive.runtime_of(data).row[0]
    for name, dtype, ndim in cable_kernels.ARRAYS:
        field = row[name]
        assert field[0] != 0 and np.all(field[1:] > 0), name
        assert len(field) == 1 + ndim and np.dtype(dtype).itemsize in (1, 4, 8)
    np.testing.assert_array_equal(row["qfrc_passive"][1:], [native.nv])
    assert row["mu"] == pytest.approx(0.15) and row["compute_pieces"] == 0  # friction reads the native pieces
    cp.release_data(data)


def test_the_dispatch_table_follows_the_hooks_and_frees_with_the_data() -> None:
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    data = cp.make_data(native)
    key = data._address
    runtime = passive.runtime_of(data)
    assert runtime is not None and _slot(data) is not None and runtime.row["friction"][0] == 0  # native only
    assert mujoco.get_mjcb_passive() is passive.installed_callback()
    handle = fr.install_cable_friction(native, data, CableFrictionConfig())
    assert runtime.row["friction"][0] == 1 and handle.runtime is runtime
    handle.uninstall()
    assert runtime.row["friction"][0] == 0 and _slot(data) is not None  # the native hook stays
    del data, runtime, handle
    gc.collect()
    assert key not in passive._DISPATCH.runtimes  # dropped when the MjData is freed
    assert not np.any(passive._DISPATCH.table[0]["data"] == key)
    assert (mujoco.get_mjcb_passive() is None) == (not passive._DISPATCH.runtimes)


def test_a_kernel_error_flag_reaches_the_hooks_error() -> None:
    """A kernel error inside the cfunc sets the row's flag (C cannot raise); check() reports it."""
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    data = cp.make_data(native)
    handle = fr.install_cable_friction(native, data, CableFrictionConfig())
    mujoco.mj_step(native, data)
    assert handle.error is None
    handle.runtime.row["err_friction"] = 1
    assert isinstance(handle.error, RuntimeError)
    with pytest.raises(RuntimeError, match="cable friction failed"):
        handle.check()
    cp.release_data(data)


def test_an_interrupt_inside_the_fallback_callback_is_kept_and_reraised(fallback: None,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C landing inside the Python fallback callback cannot propagate through C: it is kept
    and re-raised by check() after mj_step, not swallowed (the run then looked diverged)."""
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    data = cp.make_data(native)
    handle = fr.install_cable_friction(native, data, CableFrictionConfig())

    def interrupted(rows: np.ndarray) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(passive, "friction_forces", interrupted)
    mujoco.mj_step(native, data)  # the callback runs inside; nothing escapes through C
    assert isinstance(handle.error, KeyboardInterrupt)
    with pytest.raises(KeyboardInterrupt):
        handle.check()
    cp.release_data(data)
