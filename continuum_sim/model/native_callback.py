"""The passive-force callback compiled: a numba ``cfunc`` that runs the cable kernels without Python.

MuJoCo calls its passive callback once per step (12,834 times a default run). The Python
callback (``friction._passive_callback``, kept as the fallback: ``CONTINUUM_SIM_PY_CALLBACK=1``)
spends ~15 µs of interpreter per step around the two kernels (ctypes entry, registry
lookups, two numba dispatches of ~40 arguments, ``mj_fwdActuation`` through pybind). This
module's :func:`_callback` does the same from C:

* :data:`TABLE`, one int64 array allocated once at import (its address never changes),
  holds per registered MjData a row: its address, its model's, which hooks run (the native
  cable path, then cable friction), friction's scalars, error flags and the address and
  shape of every array the two kernels take (:data:`NATIVE_ARRAYS`, :data:`FRICTION_ARRAYS`).
  The header holds ``mj_fwdActuation``'s C address, the rows in use, the native models'
  addresses and the "unregistered data of a native model" flag.
* The cfunc finds the table through an external symbol (``llvmlite.binding.add_symbol``
  binds it to the table's address at run time), so numba's disk cache stays valid across
  processes; arrays are rebuilt from addresses with ``numba.carray``; ``mj_fwdActuation``
  is called through its address read from the table.
* The Python side (``friction._sync``) writes a row when hooks are registered and clears it
  before the MjData is freed; it holds the hooks (hence every array whose address is stored).
  Errors inside a kernel set the row's flag (a C callback cannot raise); the hooks' ``error``
  reads it.

The kernels are the same compiled functions the Python callback calls, with the same
argument types (C-contiguous arrays), so results are bit-identical.
"""

# ruff: noqa: ARG001
from __future__ import annotations

import glob
import hashlib
import inspect
import os
from typing import Any

import llvmlite.binding as llb
import numpy as np
from llvmlite import ir
from numba import carray, cfunc, njit, types
from numba.extending import intrinsic

SYMBOL = "continuum_sim_passive_table_v1"
MAX_MODELS = 64  # native models tracked for the unregistered-data report
MAX_SLOTS = 64  # registered MjData at once (more: the Python callback takes over)
# header
H_FWDACT, H_NSLOTS, H_NMODELS, H_PENDING = 0, 1, 2, 3
H_MODELS = 4
SLOT0 = H_MODELS + MAX_MODELS
# per-slot columns
C_DATA, C_MODEL, C_NATIVE, C_FRICTION, C_FWDACT, C_COMPUTE, C_BASE_HOLE, C_MU, C_PRESLIDING = range(9)
C_ERR_NATIVE, C_ERR_FRICTION = 9, 10
C_ARRAYS = 11

NATIVE_ARRAYS = (
    ("qvel", np.dtype(np.float64), 1),
    ("site_xpos", np.dtype(np.float64), 2),
    ("xaxis", np.dtype(np.float64), 2),
    ("xanchor", np.dtype(np.float64), 2),
    ("xmat", np.dtype(np.float64), 2),
    ("piece_psite", np.dtype(np.int64), 1),
    ("piece_csite", np.dtype(np.int64), 1),
    ("seg_jnt", np.dtype(np.int64), 2),
    ("seg_njnt", np.dtype(np.int64), 1),
    ("seg_ball", np.dtype(np.bool_), 1),
    ("piece_base", np.dtype(np.int64), 1),
    ("piece_seg", np.dtype(np.int64), 1),
    ("cable_start", np.dtype(np.int64), 1),
    ("cable_end", np.dtype(np.int64), 1),
    ("tendon_ids", np.dtype(np.int64), 1),
    ("piece_jadr", np.dtype(np.int64), 2),
    ("ten_rowadr", np.dtype(np.int64), 1),
    ("ten_rownnz", np.dtype(np.int64), 1),
    ("ten_colind", np.dtype(np.int64), 1),
    ("ten_stiffness", np.dtype(np.float64), 1),
    ("ten_damping", np.dtype(np.float64), 1),
    ("ten_spring", np.dtype(np.float64), 2),
    ("act_ids", np.dtype(np.int64), 1),
    ("act_owner", np.dtype(np.int64), 1),
    ("act_gear", np.dtype(np.float64), 1),
    ("moment_rowadr", np.dtype(np.int32), 1),
    ("length", np.dtype(np.float64), 1),
    ("direction", np.dtype(np.float64), 2),
    ("grad", np.dtype(np.float64), 2),
    ("ten_length", np.dtype(np.float64), 1),
    ("ten_J", np.dtype(np.float64), 1),
    ("ten_velocity", np.dtype(np.float64), 1),
    ("actuator_length", np.dtype(np.float64), 1),
    ("actuator_velocity", np.dtype(np.float64), 1),
    ("actuator_moment", np.dtype(np.float64), 1),
    ("qfrc_spring", np.dtype(np.float64), 1),
    ("qfrc_damper", np.dtype(np.float64), 1),
    ("qfrc_passive", np.dtype(np.float64), 1),
)

FRICTION_ARRAYS = (
    ("qpos", np.dtype(np.float64), 1),
    ("seg_ball", np.dtype(np.bool_), 1),
    ("seg_njnt", np.dtype(np.int64), 1),
    ("seg_qadr", np.dtype(np.int64), 2),
    ("seg_qref", np.dtype(np.float64), 2),
    ("seg_axes", np.dtype(np.float64), 3),
    ("seg_bpos", np.dtype(np.float64), 2),
    ("seg_bmat", np.dtype(np.float64), 3),
    ("seg_jpos", np.dtype(np.float64), 2),
    ("seg_dofadr", np.dtype(np.int64), 1),
    ("piece_seg", np.dtype(np.int64), 1),
    ("piece_parent", np.dtype(np.float64), 2),
    ("piece_child", np.dtype(np.float64), 2),
    ("cable_start", np.dtype(np.int64), 1),
    ("cable_end", np.dtype(np.int64), 1),
    ("tendon_ids", np.dtype(np.int64), 1),
    ("act_ids", np.dtype(np.int64), 1),
    ("act_owner", np.dtype(np.int64), 1),
    ("actuator_force", np.dtype(np.float64), 1),
    ("ten_stiffness", np.dtype(np.float64), 1),
    ("ten_damping", np.dtype(np.float64), 1),
    ("ten_spring", np.dtype(np.float64), 2),
    ("ten_length", np.dtype(np.float64), 1),
    ("ten_velocity", np.dtype(np.float64), 1),
    ("z", np.dtype(np.float64), 1),
    ("s_prev", np.dtype(np.float64), 1),
    ("initialised", np.dtype(np.bool_), 1),
    ("tension", np.dtype(np.float64), 1),
    ("seg_R", np.dtype(np.float64), 3),
    ("seg_w", np.dtype(np.float64), 3),
    ("length", np.dtype(np.float64), 1),
    ("direction", np.dtype(np.float64), 2),
    ("grad", np.dtype(np.float64), 2),
    ("piece_tension", np.dtype(np.float64), 1),
    ("wrap", np.dtype(np.float64), 1),
    ("qfrc", np.dtype(np.float64), 1),
)

C_FARRAYS = C_ARRAYS + 4 * len(NATIVE_ARRAYS)
ROW = C_FARRAYS + 4 * len(FRICTION_ARRAYS)
TABLE = np.zeros(SLOT0 + MAX_SLOTS * ROW, dtype=np.int64)
FTABLE = TABLE.view(np.float64)  # friction's μ and δ, stored as float64 bits


def slot_base(slot: int) -> int:
    return SLOT0 + slot * ROW


def fill_arrays(row: np.ndarray, first: int, specs: tuple[tuple[str, np.dtype, int], ...], arrays: tuple[Any, ...]) -> bool:
    """Write the address and shape of each array into ``row`` from column ``first`` (False: one does not fit its spec)."""
    if len(arrays) != len(specs):
        return False
    for i, ((_, dtype, ndim), a) in enumerate(zip(specs, arrays)):
        if not isinstance(a, np.ndarray) or a.dtype != dtype or a.ndim != ndim or not a.flags.c_contiguous \
                or not a.flags.writeable:
            return False
        c = first + 4 * i
        row[c] = a.ctypes.data
        row[c + 1:c + 4] = 0
        row[c + 1:c + 1 + ndim] = a.shape
    return True


# ------------------------------------------------------------------ compiled parts
@intrinsic
def _table_address(typingctx):
    def codegen(context, builder, signature, args):
        try:
            gv = builder.module.get_global(SYMBOL)
        except KeyError:
            gv = ir.GlobalVariable(builder.module, ir.IntType(8), SYMBOL)
            gv.linkage = "external"
        return builder.ptrtoint(gv, ir.IntType(64))

    return types.int64(), codegen

@intrinsic
def _ptr(typingctx, address):
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], ir.IntType(8).as_pointer())

    return types.voidptr(types.int64), codegen

@intrinsic
def _address(typingctx, pointer):
    def codegen(context, builder, signature, args):
        return builder.ptrtoint(args[0], ir.IntType(64))

    return types.int64(types.voidptr), codegen

@intrinsic
def _call_void2(typingctx, fn, a, b):
    def codegen(context, builder, signature, args):
        p = ir.IntType(8).as_pointer()
        target = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [p, p]).as_pointer())
        builder.call(target, [args[1], args[2]])
        return context.get_dummy_value()

    return types.void(types.int64, types.voidptr, types.voidptr), codegen


_native_cables: Any = None  # the kernels, bound by build()
_friction_forces: Any = None


def _run_native(t, b):  # pragma: no cover - compiled
    qvel = carray(_ptr(t[b + 0]), (t[b + 0 + 1],), np.float64)
    site_xpos = carray(_ptr(t[b + 4]), (t[b + 4 + 1], t[b + 4 + 2],), np.float64)
    xaxis = carray(_ptr(t[b + 8]), (t[b + 8 + 1], t[b + 8 + 2],), np.float64)
    xanchor = carray(_ptr(t[b + 12]), (t[b + 12 + 1], t[b + 12 + 2],), np.float64)
    xmat = carray(_ptr(t[b + 16]), (t[b + 16 + 1], t[b + 16 + 2],), np.float64)
    piece_psite = carray(_ptr(t[b + 20]), (t[b + 20 + 1],), np.int64)
    piece_csite = carray(_ptr(t[b + 24]), (t[b + 24 + 1],), np.int64)
    seg_jnt = carray(_ptr(t[b + 28]), (t[b + 28 + 1], t[b + 28 + 2],), np.int64)
    seg_njnt = carray(_ptr(t[b + 32]), (t[b + 32 + 1],), np.int64)
    seg_ball = carray(_ptr(t[b + 36]), (t[b + 36 + 1],), np.bool_)
    piece_base = carray(_ptr(t[b + 40]), (t[b + 40 + 1],), np.int64)
    piece_seg = carray(_ptr(t[b + 44]), (t[b + 44 + 1],), np.int64)
    cable_start = carray(_ptr(t[b + 48]), (t[b + 48 + 1],), np.int64)
    cable_end = carray(_ptr(t[b + 52]), (t[b + 52 + 1],), np.int64)
    tendon_ids = carray(_ptr(t[b + 56]), (t[b + 56 + 1],), np.int64)
    piece_jadr = carray(_ptr(t[b + 60]), (t[b + 60 + 1], t[b + 60 + 2],), np.int64)
    ten_rowadr = carray(_ptr(t[b + 64]), (t[b + 64 + 1],), np.int64)
    ten_rownnz = carray(_ptr(t[b + 68]), (t[b + 68 + 1],), np.int64)
    ten_colind = carray(_ptr(t[b + 72]), (t[b + 72 + 1],), np.int64)
    ten_stiffness = carray(_ptr(t[b + 76]), (t[b + 76 + 1],), np.float64)
    ten_damping = carray(_ptr(t[b + 80]), (t[b + 80 + 1],), np.float64)
    ten_spring = carray(_ptr(t[b + 84]), (t[b + 84 + 1], t[b + 84 + 2],), np.float64)
    act_ids = carray(_ptr(t[b + 88]), (t[b + 88 + 1],), np.int64)
    act_owner = carray(_ptr(t[b + 92]), (t[b + 92 + 1],), np.int64)
    act_gear = carray(_ptr(t[b + 96]), (t[b + 96 + 1],), np.float64)
    moment_rowadr = carray(_ptr(t[b + 100]), (t[b + 100 + 1],), np.int32)
    length = carray(_ptr(t[b + 104]), (t[b + 104 + 1],), np.float64)
    direction = carray(_ptr(t[b + 108]), (t[b + 108 + 1], t[b + 108 + 2],), np.float64)
    grad = carray(_ptr(t[b + 112]), (t[b + 112 + 1], t[b + 112 + 2],), np.float64)
    ten_length = carray(_ptr(t[b + 116]), (t[b + 116 + 1],), np.float64)
    ten_J = carray(_ptr(t[b + 120]), (t[b + 120 + 1],), np.float64)
    ten_velocity = carray(_ptr(t[b + 124]), (t[b + 124 + 1],), np.float64)
    actuator_length = carray(_ptr(t[b + 128]), (t[b + 128 + 1],), np.float64)
    actuator_velocity = carray(_ptr(t[b + 132]), (t[b + 132 + 1],), np.float64)
    actuator_moment = carray(_ptr(t[b + 136]), (t[b + 136 + 1],), np.float64)
    qfrc_spring = carray(_ptr(t[b + 140]), (t[b + 140 + 1],), np.float64)
    qfrc_damper = carray(_ptr(t[b + 144]), (t[b + 144 + 1],), np.float64)
    qfrc_passive = carray(_ptr(t[b + 148]), (t[b + 148 + 1],), np.float64)
    _native_cables(
        qvel, site_xpos, xaxis, xanchor, xmat, piece_psite, piece_csite, seg_jnt, seg_njnt, seg_ball,
        piece_base, piece_seg, cable_start, cable_end, tendon_ids, piece_jadr, ten_rowadr, ten_rownnz,
        ten_colind, ten_stiffness, ten_damping, ten_spring, act_ids, act_owner, act_gear, moment_rowadr,
        length, direction, grad, ten_length, ten_J, ten_velocity, actuator_length, actuator_velocity,
        actuator_moment, qfrc_spring, qfrc_damper, qfrc_passive,
    )


def _run_friction(t, ft, s, f):  # pragma: no cover - compiled
    f_qpos = carray(_ptr(t[f + 0]), (t[f + 0 + 1],), np.float64)
    f_seg_ball = carray(_ptr(t[f + 4]), (t[f + 4 + 1],), np.bool_)
    f_seg_njnt = carray(_ptr(t[f + 8]), (t[f + 8 + 1],), np.int64)
    f_seg_qadr = carray(_ptr(t[f + 12]), (t[f + 12 + 1], t[f + 12 + 2],), np.int64)
    f_seg_qref = carray(_ptr(t[f + 16]), (t[f + 16 + 1], t[f + 16 + 2],), np.float64)
    f_seg_axes = carray(_ptr(t[f + 20]), (t[f + 20 + 1], t[f + 20 + 2], t[f + 20 + 3],), np.float64)
    f_seg_bpos = carray(_ptr(t[f + 24]), (t[f + 24 + 1], t[f + 24 + 2],), np.float64)
    f_seg_bmat = carray(_ptr(t[f + 28]), (t[f + 28 + 1], t[f + 28 + 2], t[f + 28 + 3],), np.float64)
    f_seg_jpos = carray(_ptr(t[f + 32]), (t[f + 32 + 1], t[f + 32 + 2],), np.float64)
    f_seg_dofadr = carray(_ptr(t[f + 36]), (t[f + 36 + 1],), np.int64)
    f_piece_seg = carray(_ptr(t[f + 40]), (t[f + 40 + 1],), np.int64)
    f_piece_parent = carray(_ptr(t[f + 44]), (t[f + 44 + 1], t[f + 44 + 2],), np.float64)
    f_piece_child = carray(_ptr(t[f + 48]), (t[f + 48 + 1], t[f + 48 + 2],), np.float64)
    f_cable_start = carray(_ptr(t[f + 52]), (t[f + 52 + 1],), np.int64)
    f_cable_end = carray(_ptr(t[f + 56]), (t[f + 56 + 1],), np.int64)
    f_tendon_ids = carray(_ptr(t[f + 60]), (t[f + 60 + 1],), np.int64)
    f_act_ids = carray(_ptr(t[f + 64]), (t[f + 64 + 1],), np.int64)
    f_act_owner = carray(_ptr(t[f + 68]), (t[f + 68 + 1],), np.int64)
    f_actuator_force = carray(_ptr(t[f + 72]), (t[f + 72 + 1],), np.float64)
    f_ten_stiffness = carray(_ptr(t[f + 76]), (t[f + 76 + 1],), np.float64)
    f_ten_damping = carray(_ptr(t[f + 80]), (t[f + 80 + 1],), np.float64)
    f_ten_spring = carray(_ptr(t[f + 84]), (t[f + 84 + 1], t[f + 84 + 2],), np.float64)
    f_ten_length = carray(_ptr(t[f + 88]), (t[f + 88 + 1],), np.float64)
    f_ten_velocity = carray(_ptr(t[f + 92]), (t[f + 92 + 1],), np.float64)
    f_z = carray(_ptr(t[f + 96]), (t[f + 96 + 1],), np.float64)
    f_s_prev = carray(_ptr(t[f + 100]), (t[f + 100 + 1],), np.float64)
    f_initialised = carray(_ptr(t[f + 104]), (t[f + 104 + 1],), np.bool_)
    f_tension = carray(_ptr(t[f + 108]), (t[f + 108 + 1],), np.float64)
    f_seg_R = carray(_ptr(t[f + 112]), (t[f + 112 + 1], t[f + 112 + 2], t[f + 112 + 3],), np.float64)
    f_seg_w = carray(_ptr(t[f + 116]), (t[f + 116 + 1], t[f + 116 + 2], t[f + 116 + 3],), np.float64)
    f_length = carray(_ptr(t[f + 120]), (t[f + 120 + 1],), np.float64)
    f_direction = carray(_ptr(t[f + 124]), (t[f + 124 + 1], t[f + 124 + 2],), np.float64)
    f_grad = carray(_ptr(t[f + 128]), (t[f + 128 + 1], t[f + 128 + 2],), np.float64)
    f_piece_tension = carray(_ptr(t[f + 132]), (t[f + 132 + 1],), np.float64)
    f_wrap = carray(_ptr(t[f + 136]), (t[f + 136 + 1],), np.float64)
    f_qfrc = carray(_ptr(t[f + 140]), (t[f + 140 + 1],), np.float64)

    _friction_forces(
        f_qpos, f_seg_ball, f_seg_njnt, f_seg_qadr, f_seg_qref, f_seg_axes, f_seg_bpos, f_seg_bmat,
        f_seg_jpos, f_seg_dofadr, f_piece_seg, f_piece_parent, f_piece_child, f_cable_start, f_cable_end,
        f_tendon_ids, f_act_ids, f_act_owner, f_actuator_force, f_ten_stiffness, f_ten_damping, f_ten_spring,
        f_ten_length, f_ten_velocity,
        ft[s + C_MU], ft[s + C_PRESLIDING], t[s + C_BASE_HOLE] != 0,
        f_z, f_s_prev, f_initialised, f_tension, f_seg_R, f_seg_w, f_length, f_direction, f_grad,
        f_piece_tension, f_wrap, f_qfrc,
        t[s + C_COMPUTE] != 0,
    )


def _callback(model_ptr, data_ptr):  # pragma: no cover - compiled
    base = _table_address()
    t = carray(_ptr(base), (SLOT0 + MAX_SLOTS * ROW,), np.int64)
    ft = carray(_ptr(base), (SLOT0 + MAX_SLOTS * ROW,), np.float64)
    d = _address(data_ptr)
    m = _address(model_ptr)
    for slot in range(t[H_NSLOTS]):
        s = SLOT0 + slot * ROW
        if t[s + C_DATA] != d or d == 0:
            continue
        if t[s + C_MODEL] != m:
            return
        if t[s + C_NATIVE] != 0:
            try:
                _run_native(t, s + C_ARRAYS)
            except Exception:  # noqa: BLE001 - a C callback cannot raise: flagged for the hook's error
                t[s + C_ERR_NATIVE] = 1
                return
        if t[s + C_FRICTION] != 0:
            if t[s + C_FWDACT] != 0:
                _call_void2(t[H_FWDACT], model_ptr, data_ptr)
            try:
                _run_friction(t, ft, s, s + C_FARRAYS)
            except Exception:  # noqa: BLE001
                t[s + C_ERR_FRICTION] = 1
        return
    for k in range(t[H_NMODELS]):
        if t[H_MODELS + k] == m and m != 0:
            t[H_PENDING] = 1
            return


_BUILT: list[Any] = []


def _kernel_stamp() -> str:
    """Hash of the kernels' sources: numba's cache of this module does not see edits to them."""
    from . import cable_path, friction

    text = inspect.getsource(cable_path) + inspect.getsource(friction)
    return hashlib.sha256(text.encode()).hexdigest()


def _cache_ok() -> bool:
    """Drop this module's numba cache when the kernels it inlines changed since it was written."""
    here = os.path.dirname(os.path.abspath(__file__))
    cache = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(here, "__pycache__")
    stamp = _kernel_stamp()
    path = os.path.join(cache, "native_callback.kernels.sha256")
    try:
        with open(path) as fh:
            if fh.read().strip() == stamp:
                return True
    except OSError:
        pass
    try:
        for old in glob.glob(os.path.join(cache, "**", "native_callback.*.nb[ic]"), recursive=True):
            os.remove(old)
        os.makedirs(cache, exist_ok=True)
        with open(path, "w") as fh:
            fh.write(stamp)
    except OSError:
        return False
    return True


def _fwd_actuation_address() -> int:
    """``mj_fwdActuation``'s C address (the callback calls it before friction)."""
    from .jit import mujoco_symbols

    found = mujoco_symbols("mj_fwdActuation")
    if found is None:
        raise OSError("libmujoco not found next to the mujoco bindings")
    return found[0]


def build() -> Any:
    """The compiled callback's ctypes function pointer (compiled, or loaded from numba's cache, once)."""
    if _BUILT:
        return _BUILT[0]
    from . import cable_path, friction

    g = globals()
    g["_native_cables"] = cable_path.kernels()["native_cables"]
    g["_friction_forces"] = friction.kernels()["friction_forces"]
    llb.add_symbol(SYMBOL, TABLE.ctypes.data)
    TABLE[H_FWDACT] = _fwd_actuation_address()

    cache = _cache_ok()
    for name in ("_run_native", "_run_friction"):
        g[name] = njit(cache=cache, fastmath=False, nogil=True)(g[name])
    compiled = cfunc(types.void(types.voidptr, types.voidptr), cache=cache, nogil=True)(_callback)
    _BUILT.append(compiled.ctypes)
    return _BUILT[0]
