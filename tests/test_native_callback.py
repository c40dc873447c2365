"""The compiled passive callback (numba cfunc, ``model/native_callback.py``) vs the Python fallback."""

from __future__ import annotations

import gc

import mujoco
import numpy as np
import pytest
from test_cable_path import _arm_root, _drive

from continuum_sim.model import cable_path as cp
from continuum_sim.model import friction as fr


def _run(compiled: bool, monkeypatch: pytest.MonkeyPatch) -> tuple[np.ndarray, bool]:
    monkeypatch.setattr(fr, "COMPILED_CALLBACK", compiled)
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    data = cp.make_data(native)
    handle = fr.install_cable_friction(native, data, fr.CableFrictionConfig(), kernel=cp.native_cables(native).data_kernel(data))
    used = bool(fr._COMPILED) and mujoco.get_mjcb_passive() is fr._COMPILED[0]
    state = _drive(native, data, 150, seed=3)
    handle.check()
    out = np.r_[state, data.qfrc_passive, data.ten_J, data.actuator_moment, handle.z, handle.piece_tension]
    handle.uninstall()
    cp.release_data(data)
    return out, used


def test_compiled_callback_is_bit_identical_to_the_python_one(monkeypatch: pytest.MonkeyPatch) -> None:
    compiled, used = _run(True, monkeypatch)
    assert used, "the compiled callback was not installed"
    python, used_python = _run(False, monkeypatch)
    assert not used_python
    np.testing.assert_array_equal(compiled, python)
    assert (mujoco.get_mjcb_passive() is None) == (not fr._REGISTRY)  # ours gone when nothing is registered


def test_compiled_callback_table_follows_registrations() -> None:
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    data = cp.make_data(native)
    key = data._address
    assert key in fr._SLOTS and fr._SLOT_HOOKS[key][1] is None  # native hook only
    handle = fr.install_cable_friction(native, data, fr.CableFrictionConfig(), kernel=cp.native_cables(native).data_kernel(data))
    assert fr._SLOT_HOOKS[key][1] is handle
    nc = fr._table()
    assert nc.TABLE[nc.slot_base(fr._SLOTS[key]) + nc.C_DATA] == key
    handle.uninstall()
    assert fr._SLOT_HOOKS[key][1] is None
    del data
    gc.collect()
    assert key not in fr._SLOTS  # the row is cleared when the MjData is freed
    assert (mujoco.get_mjcb_passive() is None) == (not fr._REGISTRY)  # ours gone when nothing is registered


def test_a_kernel_error_flag_reaches_the_hooks_error() -> None:
    """A kernel error inside the cfunc sets the row's flag (C cannot raise); check() reports it."""
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    data = cp.make_data(native)
    handle = fr.install_cable_friction(native, data, fr.CableFrictionConfig(), kernel=cp.native_cables(native).data_kernel(data))
    mujoco.mj_step(native, data)
    assert handle.error is None
    nc = fr._table()
    nc.TABLE[nc.slot_base(fr._SLOTS[data._address]) + nc.C_ERR_FRICTION] = 1
    assert isinstance(handle.error, RuntimeError)
    with pytest.raises(RuntimeError, match="cable friction failed"):
        handle.check()
    handle.uninstall()
    cp.release_data(data)


def test_a_replaced_apply_falls_back_to_the_python_callback() -> None:
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    data = cp.make_data(native)
    handle = fr.install_cable_friction(native, data, fr.CableFrictionConfig(), kernel=cp.native_cables(native).data_kernel(data))
    assert mujoco.get_mjcb_passive() is fr._COMPILED[0]
    calls: list[int] = []
    handle.apply = lambda model, d: calls.append(1)  # type: ignore[method-assign]
    assert mujoco.get_mjcb_passive() is fr._C_CALLBACK[0]
    mujoco.mj_step(native, data)
    assert calls
    handle.apply = fr.CableFriction.apply.__get__(handle)  # set back as undoing a monkeypatch does: table again
    assert mujoco.get_mjcb_passive() is fr._COMPILED[0]
    assert data._address not in fr._UNFIT
    handle.apply = lambda model, d: calls.append(1)  # type: ignore[method-assign]
    del handle.apply  # deleted: the class's apply again
    assert mujoco.get_mjcb_passive() is fr._COMPILED[0]
    handle.uninstall()
    assert mujoco.get_mjcb_passive() is fr._COMPILED[0]  # only table-ready hooks left
    cp.release_data(data)
    assert (mujoco.get_mjcb_passive() is None) == (not fr._REGISTRY)  # ours gone when nothing is registered


def test_without_mujocos_library_by_path_the_python_callback_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled callback calls mj_fwdActuation by address; where the library is not found
    (``jit.mujoco_symbols`` None) building it fails and the process keeps the Python callback."""
    from continuum_sim.model import jit
    from continuum_sim.model import native_callback as nc

    monkeypatch.setattr(jit, "mujoco_symbols", lambda *names: None)
    monkeypatch.setattr(fr, "_COMPILED", [])
    monkeypatch.setattr(fr, "_UNAVAILABLE", [])
    monkeypatch.setattr(nc, "_BUILT", [])
    native, _ = cp.compile_native(_arm_root("hinge_pair"))
    data = cp.make_data(native)
    assert fr._UNAVAILABLE and mujoco.get_mjcb_passive() is fr._C_CALLBACK[0]
    handle = fr.install_cable_friction(native, data, fr.CableFrictionConfig(),
                                       kernel=cp.native_cables(native).data_kernel(data))
    _drive(native, data, 20, seed=1)
    handle.check()
    assert np.all(np.isfinite(data.qpos)) and np.any(data.ten_length)  # the cables were evaluated
    handle.uninstall()
    cp.release_data(data)
