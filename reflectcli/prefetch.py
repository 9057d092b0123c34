"""Asking the memory system for data before a kernel reads it (numba).

A kernel that reads rows of arrays in an order it learns only as it goes (a triangle id per
pixel) waits for each row in turn; `prefetch` names the row it will read a few steps ahead,
so several such reads are on their way at once. Only a hint: it changes no value."""

from __future__ import annotations

import numba
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

_INTERPRETED = bool(numba.config.DISABLE_JIT)


def _prefetch_intrinsic(write: int):
    """An intrinsic (ary, index): llvm.prefetch (read, or with `write` 1 for a write: the
    line comes ready to be stored to; keep in all levels) of the first element of
    ary[index]."""

    @intrinsic
    def _prefetch(typingctx, ary, index):
        sig = types.void(ary, index)

        def codegen(context, builder, signature, args):
            aryty = signature.args[0]
            a = context.make_array(aryty)(context, builder, args[0])
            zero = context.get_constant(types.intp, 0)
            at = builder.sext(args[1], ir.IntType(64)) if args[1].type.width < 64 else args[1]
            ptr = cgutils.get_item_pointer(context, builder, aryty, a,
                                           [at] + [zero] * (aryty.ndim - 1))
            i8p = ir.IntType(8).as_pointer()
            i32 = ir.IntType(32)
            fn = cgutils.get_or_insert_function(
                builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]),
                "llvm.prefetch.p0i8")
            builder.call(fn, [builder.bitcast(ptr, i8p), i32(write), i32(3), i32(1)])
            return context.get_dummy_value()

        return sig, codegen

    return _prefetch


_prefetch_row = _prefetch_intrinsic(0)
_prefetch_row_write = _prefetch_intrinsic(1)


@njit(cache=True, inline="always")
def prefetch(ary, index):
    """Hint that ary[index] (its first element) will be read soon; nothing happens to
    `index` outside the array's first axis bounds but a wasted hint (with numba's JIT off,
    nothing at all)."""
    if _INTERPRETED:
        return
    if 0 <= index < ary.shape[0]:
        _prefetch_row(ary, index)


@njit(cache=True, inline="always")
def prefetch_write(ary, index):
    """`prefetch` for a write: hint that ary[index] will be written soon."""
    if _INTERPRETED:
        return
    if 0 <= index < ary.shape[0]:
        _prefetch_row_write(ary, index)
