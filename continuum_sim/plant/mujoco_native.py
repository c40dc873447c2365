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
