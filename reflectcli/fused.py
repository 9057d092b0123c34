"""a * b + c rounded once (a fused multiply-add) in numba kernels.

numpy's `@` on this machine kind runs OpenBLAS, whose kernels sum products with fused
multiply-adds: a kernel that is to give `@`'s bits (virtual/screen.py) has to fuse them
where it does. numba has no fma of its own; this is LLVM's (one instruction where the CPU
has it, correctly rounded in software where not, so the same bits everywhere)."""

from __future__ import annotations

import math
from fractions import Fraction

import numba
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

_INTERPRETED = bool(numba.config.DISABLE_JIT)


@intrinsic
def _llvm_fma(typingctx, a, b, c):
    """llvm.fma.f64(a, b, c): a * b + c with one rounding."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        double = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [double],
                                              ir.FunctionType(double, [double] * 3))
        return builder.call(fn, args)

    return sig, codegen


def _exact_fma(a: float, b: float, c: float) -> float:
    """fma with numba's JIT off: the exact a * b + c, rounded once; a * b + c where an
    operand is not finite (the infinities and NaN are then the same)."""
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
        return a * b + c
    return float(Fraction(a) * Fraction(b) + Fraction(c))


@njit(cache=True, inline="always")
def fma(a, b, c):
    """a * b + c with one rounding (float64)."""
    if _INTERPRETED:
        return _exact_fma(a, b, c)
    return _llvm_fma(float(a), float(b), float(c))
