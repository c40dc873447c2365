"""Raw addresses in compiled kernels: MuJoCo's buffers and its C functions called directly.

The cutter's per-step kernel reads MuJoCo's arrays through their addresses (each
``data.<field>`` access from Python builds a new array object; an address is one int64 in
a record) and calls ``mj_jac``/``mj_solveM`` through their addresses in the loaded
libmujoco (``model.jit.mujoco_symbols``). Addresses come in as arguments, none is baked
into the code, so numba's on-disk cache stays valid. Where the library is not found the
caller takes the public API (``mujoco.mj_jac``/``mj_solveM``) between two kernel calls:
the same kernels, the same numbers (``tests/test_cutter.py``).
"""

from __future__ import annotations

from typing import Any

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

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
    from ..model import jit

    found = jit.mujoco_symbols("mj_jac", "mj_solveM")
    return None if found is None else (found[0], found[1])
