"""Raw addresses: the one module that finds MuJoCo's C functions by address and reads buffers from addresses.

Why: MuJoCo calls its passive-force callback from C once per step; the compiled callback
(``passive``) runs the cable kernels there without entering Python, which needs (a) the
address of ``mj_fwdActuation`` in the loaded library and (b) numba views of the arrays whose
addresses a per-data record holds. Where the library is not found by path
(:func:`mujoco_symbols` None) the callers take MuJoCo's public Python API instead
(``passive``'s fallback, tested in ``tests/test_native_callback.py``).
"""

# ruff: noqa: ARG001 - numba's intrinsic and codegen signatures are fixed
from __future__ import annotations

from typing import Any

import numpy as np
from llvmlite import ir
from numba import carray, types
from numba.extending import intrinsic, overload


def mujoco_symbols(*names: str) -> tuple[int, ...] | None:
    """The C addresses of MuJoCo functions ``names`` in the library the bindings loaded; None
    where the library or a symbol is not found (the caller takes MuJoCo's Python API)."""
    import ctypes
    import glob
    import os

    import mujoco

    here = os.path.dirname(mujoco.__file__)
    libraries = sorted(p for pattern in ("libmujoco*.so*", "libmujoco*.dylib", "mujoco*.dll")
                       for p in glob.glob(os.path.join(here, pattern)))
    for path in libraries:
        try:
            lib = ctypes.CDLL(path)
            addresses = tuple(int(ctypes.cast(getattr(lib, name), ctypes.c_void_p).value or 0) for name in names)
        except (OSError, AttributeError):
            continue
        if all(addresses):
            return addresses
    return None


@intrinsic
def pointer(typingctx: Any, address: Any) -> Any:
    """The int64 ``address`` as a ``void*`` (numba)."""
    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.inttoptr(args[0], ir.IntType(8).as_pointer())

    return types.voidptr(types.int64), codegen


@intrinsic
def address(typingctx: Any, ptr: Any) -> Any:
    """The ``void*`` ``ptr`` as an int64 (numba)."""
    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.ptrtoint(args[0], ir.IntType(64))

    return types.int64(types.voidptr), codegen


@intrinsic
def call_void2(typingctx: Any, fn: Any, a: Any, b: Any) -> Any:
    """Call the C function ``void fn(void*, void*)`` at address ``fn`` (e.g. ``mj_fwdActuation(m, d)``)."""
    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        p = ir.IntType(8).as_pointer()
        target = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [p, p]).as_pointer())
        builder.call(target, [args[1], args[2]])
        return context.get_dummy_value()

    return types.void(types.int64, types.voidptr, types.voidptr), codegen


def symbol_address(symbol: str) -> Any:
    """A numba intrinsic returning the address bound to the external ``symbol`` at run time
    (``llvmlite.binding.add_symbol``): compiled code finds a buffer allocated by this process
    without baking the address in, so numba's disk cache stays valid across processes."""
    @intrinsic
    def _address_of(typingctx: Any) -> Any:
        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            try:
                gv = builder.module.get_global(symbol)
            except KeyError:
                gv = ir.GlobalVariable(builder.module, ir.IntType(8), symbol)
                gv.linkage = "external"
            return builder.ptrtoint(gv, ir.IntType(64))

        return types.int64(), codegen

    return _address_of


def bind_symbol(symbol: str, buffer: np.ndarray) -> None:
    """Bind the external ``symbol`` to ``buffer``'s address (it must live as long as the process)."""
    import llvmlite.binding as llb

    llb.add_symbol(symbol, buffer.ctypes.data)


def view(field, dtype):  # (numba matches the overloads' unannotated signature)
    """The array of ``dtype`` a record's array field (address, shape...) describes (numba only)."""
    raise NotImplementedError("compiled code only")


@overload(view)
def _view(field, dtype):  # (unannotated: numba compares it with the lambdas')
    ndim = field.shape[0] - 1
    if ndim == 1:
        return lambda field, dtype: carray(pointer(field[0]), (field[1],), dtype)
    if ndim == 2:
        return lambda field, dtype: carray(pointer(field[0]), (field[1], field[2]), dtype)
    if ndim == 3:
        return lambda field, dtype: carray(pointer(field[0]), (field[1], field[2], field[3]), dtype)
    return None


# The cutter kernel reads MuJoCo arrays through their addresses and calls mj_jac/mj_solveM by
# address (addresses come in as arguments, none is baked into the code, so numba's on-disk cache
# stays valid); where the library is not found the cutter calls the public API between two
# kernel calls (tests/test_cutter.py).
_PTR = ir.IntType(8).as_pointer()


def _f64(_typingctx: Any, _addr: Any) -> Any:
    """An int64 address as a float64 pointer (for ``numba.carray``)."""
    def codegen(context: Any, builder: Any, _signature: Any, args: Any) -> Any:
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))
    return types.CPointer(types.float64)(types.int64), codegen


def _caller(n_pointers: int) -> Any:
    """The typing of ``void f(void*, ...(n_pointers), int)`` called through an int64 address."""
    def codegen(context: Any, builder: Any, _signature: Any, values: Any) -> Any:
        fnty = ir.FunctionType(ir.VoidType(), [_PTR] * n_pointers + [ir.IntType(32)])
        fn = builder.inttoptr(values[0], fnty.as_pointer())
        builder.call(fn, [builder.inttoptr(v, _PTR) for v in values[1:-1]] + [builder.trunc(values[-1], ir.IntType(32))])
        return context.get_dummy_value()
    return types.void(*([types.int64] * (n_pointers + 2))), codegen


def _call_jac(_typingctx: Any, _fn: Any, _m: Any, _d: Any, _jacp: Any, _jacr: Any, _point: Any, _body: Any) -> Any:
    """``mj_jac(m, d, jacp, jacr, point, body)`` through its address (all arguments int64)."""
    return _caller(5)


def _call_solve(_typingctx: Any, _fn: Any, _m: Any, _d: Any, _x: Any, _y: Any, _n: Any) -> Any:
    """``mj_solveM(m, d, x, y, n)`` through its address (all arguments int64)."""
    return _caller(4)


# (typed Any: numba's own hints describe the intrinsic's typing signature, not the kernel call)
f64: Any = intrinsic(_f64)
call_jac: Any = intrinsic(_call_jac)
call_solve: Any = intrinsic(_call_solve)


def mujoco_functions() -> tuple[int, int] | None:
    """The addresses of ``mj_jac`` and ``mj_solveM`` in the loaded MuJoCo library (None: not found)."""
    found = mujoco_symbols("mj_jac", "mj_solveM")
    return None if found is None else (found[0], found[1])
