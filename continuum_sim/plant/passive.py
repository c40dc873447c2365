"""THE MuJoCo passive-force callback of the process: one documented entry for every cable hook.

MuJoCo calls ``mjcb_passive`` once per step, after the position and velocity stages and
before actuation (12,834 times a default run). The cable physics MuJoCo does not have runs
there, per MjData, in this order: the native cable path (``cable_path``: the cables'
lengths, Jacobians and spring/damper forces), ``mj_fwdActuation``, cable friction
(``friction``: the capstan correction reads the actuator forces).

* :class:`PassiveRuntime`: the hooks of ONE MjData: its :data:`cable_kernels.ROW` record (the
  addresses and shapes of the arrays the kernels read and write, the friction scalars, the
  error flags), the arrays themselves (kept alive here), its own piece scratch. Hooks turn
  themselves on and off in it; it is dropped when its MjData is freed.
* The callback: a numba ``cfunc`` (no Python per step; ~15 µs a step cheaper than a Python
  callback) that finds the data's row through the dispatch table, runs the compiled kernels
  of ``cable_kernels`` on it, and calls ``mj_fwdActuation`` by address
  (``mujoco_native``). Where MuJoCo's library is not found by path, a ctypes callback runs
  the same compiled kernels on the same rows with MuJoCo's public ``mj_fwdActuation``.

Why one module-level object (:data:`_DISPATCH`): ``mjcb_passive`` is process-global. It
receives raw (mjModel*, mjData*) pointers, also for MuJoCo's internal datas while a model
compiles and for every other model of the process (sweeps, tests, ``mujoco.rollout``), so
something global must map a data address to its runtime; this is the only such object in
``plant``. It also lists the models with native cables: stepping one with an MjData that has
no runtime (its cables would have zero length) is flagged and reported by
:func:`raise_pending`.
"""

from __future__ import annotations

import ctypes
import os
import weakref
from typing import Any

import numpy as np
from numba import carray, cfunc, types

from .cable_kernels import ARRAYS, ROW, friction_forces, native_cables
from .cable_routing import CablePieces, CableRouting
from .jit import drop_stale_cache, sigint_deferred
from .mujoco_native import address, bind_symbol, call_void2, pointer, symbol_address

SYMBOL = "continuum_sim_passive_dispatch_v2"
MAX_DATAS = 256  # MjData with cable hooks at once
MAX_MODELS = 256  # native models tracked for the unregistered-data report (beyond: not reported)
DISPATCH = np.dtype([
    ("fwdact", np.int64),  # mj_fwdActuation's C address
    ("ndata", np.int64), ("pending", np.int64), ("nmodels", np.int64),
    ("models", np.int64, (MAX_MODELS,)),  # addresses of the models with native cables
    ("data", np.int64, (MAX_DATAS,)),  # addresses of the MjData with hooks (0: free)
    ("row", np.int64, (MAX_DATAS,)),  # address of each one's ROW record
], align=True)
_SPECS = {name: (dtype, ndim) for name, dtype, ndim in ARRAYS}
_UNREGISTERED = ("a model with native cables was stepped with an MjData not made by NativeCables.make_data"
                 " (its cables would have zero length)")


def _tension_sources(model: Any, routing: CableRouting) -> dict[str, np.ndarray]:
    """Each cable's tendon spring/damper and its actuators (cable-major order), read from ``model``."""
    import mujoco

    trn_tendon = int(mujoco.mjtTrn.mjTRN_TENDON)
    ids, owner = [], []
    for c, t in enumerate(routing.tendon_ids):
        for a in np.flatnonzero((model.actuator_trntype == trn_tendon) & (model.actuator_trnid[:, 0] == t)):
            ids.append(int(a))
            owner.append(c)
    return {
        "ten_stiffness": np.array(model.tendon_stiffness[routing.tendon_ids], dtype=float),
        "ten_damping": np.array(model.tendon_damping[routing.tendon_ids], dtype=float),
        "ten_spring": np.array(model.tendon_lengthspring[routing.tendon_ids], dtype=float).reshape(-1, 2),
        "act_ids": np.array(ids, dtype=np.int64),
        "act_owner": np.array(owner, dtype=np.int64),
        "act_gear": np.array([model.actuator_gear[a, 0] for a in ids], dtype=float),
    }


class PassiveRuntime:
    """The passive hooks of one (model, data) pair: the record the kernels read, the arrays it points to."""

    def __init__(self, model: Any, data: Any, routing: CableRouting) -> None:
        self.routing = routing
        self.pieces = CablePieces(routing)  # this data's own scratch: the kernels run without the GIL
        self.row = np.zeros(1, ROW)
        self.row["data"], self.row["model"] = data._address, model._address
        self.address = int(data._address)
        self._model_ref, self._data_ref = weakref.ref(model), weakref.ref(data)
        self._arrays: dict[str, np.ndarray] = {}
        self.errors: dict[str, BaseException] = {}  # raised in the Python callback, per hook
        self.sources = _tension_sources(model, routing)
        self.bind(**{name: getattr(data, name) for name in (
            "qvel", "site_xpos", "xmat", "xaxis", "xanchor", "ten_length", "ten_J", "ten_velocity", "actuator_length",
            "actuator_velocity", "actuator_moment", "moment_rowadr", "actuator_force", "qfrc_spring", "qfrc_damper",
            "qfrc_passive")})
        self.bind(**{name: getattr(routing, name) for name in (
            "piece_psite", "piece_csite", "piece_base", "piece_seg", "seg_jnt", "seg_njnt", "seg_ball", "seg_body",
            "seg_dofadr", "cable_start", "cable_end", "tendon_ids")})
        self.bind(length=self.pieces.length, direction=self.pieces.direction, grad=self.pieces.grad, **self.sources)

    def bind(self, **arrays: np.ndarray) -> None:
        """Write each array's address and shape into the record (checked against ``cable_kernels.ARRAYS``)."""
        for name, a in arrays.items():
            dtype, ndim = _SPECS[name]
            if not isinstance(a, np.ndarray) or a.dtype != dtype or a.ndim != ndim or not a.flags.c_contiguous \
                    or not a.flags.writeable:
                raise TypeError(f"passive record: {name} must be a writable C-contiguous {ndim}-d {dtype} array")
            self.row[name][0] = (a.ctypes.data, *a.shape)
            self._arrays[name] = a

    def set(self, **scalars: float) -> None:
        """Set scalar fields of the record (hook flags, friction parameters); republish."""
        for name, value in scalars.items():
            self.row[name] = value
        _DISPATCH.publish(self)

    @property
    def active(self) -> bool:
        return bool(self.row["native"][0] or self.row["friction"][0])

    def error(self, hook: str) -> BaseException | None:
        """The first error the callback met in ``hook`` ("native", "friction"); None: none."""
        if hook not in self.errors and self.row[f"err_{hook}"][0]:
            self.errors[hook] = RuntimeError(f"{hook}: a compiled kernel raised in the passive callback")
        return self.errors.get(hook)

    def run(self, model: Any, data: Any) -> None:
        """The passive stage's work through Python (the fallback callback): the same compiled kernels,
        MuJoCo's public ``mj_fwdActuation``. Errors are kept per hook (a C callback cannot raise)."""
        import mujoco

        row = self.row
        if row["native"][0]:
            try:
                native_cables(row)
            except BaseException as exc:  # noqa: BLE001 - kept for the hook's check()
                self.errors.setdefault("native", exc)
                return
        if row["friction"][0]:
            try:
                if row["fwdact"][0]:
                    mujoco.mj_fwdActuation(model, data)
                friction_forces(row)
            except BaseException as exc:  # noqa: BLE001 - Ctrl-C included: re-raised by check() after mj_step
                self.errors.setdefault("friction", exc)


class _Dispatch:
    """The process's passive callback and the runtimes it serves (module docstring: why one global object)."""

    def __init__(self) -> None:
        self.table = np.zeros(1, DISPATCH)  # allocated once: its address is bound to SYMBOL for the process
        self.runtimes: dict[int, PassiveRuntime] = {}
        self.native_models: dict[int, Any] = {}  # model address -> its NativeCables (dropped with the model)
        self.callback: Any = None  # what we install: the compiled one, or the Python fallback
        self.fallback = False

    def attach(self, model: Any, data: Any, routing: CableRouting) -> PassiveRuntime:
        runtime = self.runtimes.get(data._address)
        if runtime is not None and runtime._data_ref() is data:
            return runtime
        runtime = PassiveRuntime(model, data, routing)
        self.runtimes[runtime.address] = runtime
        weakref.finalize(data, self.drop, runtime.address, runtime)
        return runtime

    def publish(self, runtime: PassiveRuntime) -> None:
        """Put ``runtime`` in the table while it has a hook on, take it out otherwise; (un)install the callback."""
        t = self.table[0]
        slots = np.flatnonzero(t["data"] == runtime.address)
        if runtime.active and not slots.size:
            self._ensure_callback()
            free = np.flatnonzero(t["data"] == 0)
            if not free.size:
                raise RuntimeError(f"passive callback: more than {MAX_DATAS} MjData with cable hooks at once")
            k = int(free[0])
            t["row"][k] = runtime.row.ctypes.data
            t["data"][k] = runtime.address  # last: the row is complete before the callback can match it
            t["ndata"] = max(int(t["ndata"]), k + 1)
        elif not runtime.active and slots.size:
            t["data"][slots] = 0
            self._shrink()

    def drop(self, address: int, runtime: PassiveRuntime | None = None) -> None:
        """Forget the runtime of the data at ``address`` (freed, or released at the end of a run)."""
        current = self.runtimes.get(address)
        if current is None or (runtime is not None and current is not runtime):
            return
        del self.runtimes[address]
        t = self.table[0]
        t["data"][t["data"] == address] = 0
        self._shrink()

    def _shrink(self) -> None:
        t = self.table[0]
        used = np.flatnonzero(t["data"])
        t["ndata"] = int(used[-1]) + 1 if used.size else 0
        if not used.size and self.callback is not None:
            import mujoco

            if mujoco.get_mjcb_passive() is self.callback:
                mujoco.set_mjcb_passive(None)

    def _ensure_callback(self) -> None:
        import mujoco

        compile_callback()
        current = mujoco.get_mjcb_passive()
        if current is self.callback:
            return
        if current is not None:
            raise RuntimeError("another MuJoCo passive callback is installed; the cable hooks cannot share it")
        mujoco.set_mjcb_passive(self.callback)

    def track_native_model(self, model: Any, owner: Any) -> None:
        self.native_models[model._address] = owner
        weakref.finalize(model, self.drop_model, model._address)
        self._sync_models()

    def drop_model(self, address: int) -> None:
        self.native_models.pop(address, None)
        self._sync_models()

    def _sync_models(self) -> None:
        t = self.table[0]
        addresses = list(self.native_models)[:MAX_MODELS]
        t["nmodels"] = 0
        t["models"][:len(addresses)] = addresses
        t["nmodels"] = len(addresses)


_DISPATCH = _Dispatch()
bind_symbol(SYMBOL, _DISPATCH.table)  # before any compiled code that reads the table is linked


def attach(model: Any, data: Any, routing: CableRouting) -> PassiveRuntime:
    """The runtime of ``data`` (made with ``routing`` if it has none); hooks switch themselves on in it."""
    return _DISPATCH.attach(model, data, routing)


def runtime_of(data: Any) -> PassiveRuntime | None:
    """The runtime of ``data`` (None: it has no cable hooks)."""
    runtime = _DISPATCH.runtimes.get(data._address)
    return runtime if runtime is not None and runtime._data_ref() is data else None


def release(data: Any) -> None:
    """Take every hook of ``data`` out of the callback (end of a run); the callback goes when none is left."""
    runtime = runtime_of(data)
    if runtime is not None:
        _DISPATCH.drop(runtime.address, runtime)


def track_native_model(model: Any, owner: Any) -> None:
    """List ``model`` as one with native cables (``owner``: its ``NativeCables``), until it is freed."""
    _DISPATCH.track_native_model(model, owner)


def native_owner(model: Any) -> Any:
    """The object ``track_native_model`` listed for ``model`` (None: not a native model)."""
    return _DISPATCH.native_models.get(model._address)


def raise_pending() -> None:
    """Raise if a data of a native model without a runtime was stepped since the last call (flagged in the callback)."""
    t = _DISPATCH.table[0]
    if t["pending"]:
        t["pending"] = 0
        raise RuntimeError(_UNREGISTERED)


def compile_callback() -> None:
    """Compile the callback (or load it from numba's cache) now, e.g. before timing; else on the first hook."""
    if _DISPATCH.callback is None:
        _DISPATCH.callback = _build()


def installed_callback() -> Any:
    """The callback this module installs (None until a hook is first switched on)."""
    return _DISPATCH.callback


# ------------------------------------------------------------------------- the callbacks
def _python_callback(model_ptr: int | None, data_ptr: int | None) -> None:
    """The fallback (MuJoCo's library not found by path): the same kernels through ``PassiveRuntime.run``."""
    runtime = _DISPATCH.runtimes.get(data_ptr or 0)
    if runtime is None or not runtime.active:
        if (model_ptr or 0) in _DISPATCH.native_models:
            _DISPATCH.table[0]["pending"] = 1
        return
    model, data = runtime._model_ref(), runtime._data_ref()
    if model is None or data is None or model._address != model_ptr:
        return
    runtime.run(model, data)


_dispatch_address = symbol_address(SYMBOL)


def _callback(model_ptr, data_ptr):  # pragma: no cover - compiled by _build
    """The compiled callback: find the data's row, run its hooks (module docstring)."""
    t = carray(pointer(_dispatch_address()), (1,), DISPATCH)[0]
    d, m = address(data_ptr), address(model_ptr)
    if d == 0:
        return
    for k in range(t.ndata):
        if t.data[k] != d:
            continue
        rows = carray(pointer(t.row[k]), (1,), ROW)
        r = rows[0]
        if r.model != m:
            return
        if r.native != 0:
            try:
                native_cables(rows)
            except Exception:  # noqa: BLE001 - a C callback cannot raise: flagged for the hook's error
                r.err_native = 1
                return
        if r.friction != 0:
            if r.fwdact != 0:
                call_void2(t.fwdact, model_ptr, data_ptr)
            try:
                friction_forces(rows)
            except Exception:  # noqa: BLE001
                r.err_friction = 1
        return
    for k in range(t.nmodels):
        if t.models[k] == m and m != 0:
            t.pending = 1
            return


def _build() -> Any:
    """The callback to install: the compiled one where ``mj_fwdActuation``'s address is found, else the fallback."""
    from . import mujoco_native

    found = mujoco_native.mujoco_symbols("mj_fwdActuation")
    if found is None:
        _DISPATCH.fallback = True
        return ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)(_python_callback)
    _DISPATCH.table[0]["fwdact"] = found[0]
    here = os.path.dirname(os.path.abspath(__file__))
    cache = drop_stale_cache("passive", tuple(os.path.join(here, f) for f in (
        "passive.py", "cable_kernels.py", "mujoco_native.py")), ("passive",))
    with sigint_deferred():  # compile (or load) here, not inside the C callback
        return cfunc(types.void(types.voidptr, types.voidptr), cache=cache, nogil=True)(_callback).ctypes
