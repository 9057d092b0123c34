"""Work handed to whichever thread is free, in numba's parallel loops.

numba's OpenMP layer gives each thread a fixed share of a `prange`'s items, even under
`numba.parallel_chunksize(1)` (measured: item 0 thirty times heavier than the rest, 8 items
on 2 threads, went 0 0 0 0 1 1 1 1). A kernel that wants dynamic hand-out loops
`for worker in prange(threads)` (one item per thread) and lets each worker `claim` the
next piece of work from a shared counter until none is left: a thread that lost its core,
or met the costly pieces, leaves the rest to the others. Which worker did what must not
change the result (each kernel says why it does not).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

_INTERPRETED = bool(numba.config.DISABLE_JIT)

# an image kernel's piece of work: a band of rows (a mirror's pixels bunch in some rows: split
# evenly between 2 threads, one got 70% of a teapot-box mirror's distmap samples)
ROWS_PER_CLAIM = 4


@intrinsic
def _fetch_add_one(typingctx, counter):
    """counter[0] += 1 as one atomic step (an int64 array); the value before."""
    sig = types.int64(counter)

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary,
                                       [context.get_constant(types.intp, 0)])
        return builder.atomic_rmw("add", ptr, context.get_constant(types.int64, 1), "seq_cst")

    return sig, codegen


@njit(cache=True, inline="always")
def claim(counter):
    """The next piece of work: counter[0] (an int64 array of one), then one more, atomic
    across the threads (with numba's JIT off, plain Python on one thread)."""
    if _INTERPRETED:
        k = counter[0]
        counter[0] = k + 1
        return k
    return _fetch_add_one(counter)


@njit(cache=True, inline="always")
def claim_rows(counter, h):
    """The next band of rows [y0, y1) of an image h rows high (ROWS_PER_CLAIM of them),
    claimed as `claim` does; an empty band (y0 == y1) when none is left."""
    y0 = min(claim(counter) * ROWS_PER_CLAIM, h)
    return y0, min(y0 + ROWS_PER_CLAIM, h)


@njit(cache=True)
def counter():
    """A `claim` counter at zero. Made here, in a plain function: written as np.zeros(1) in
    a parallel kernel it would be a parallel loop of its own (numba turns array constructors
    there into parallel loops), one more wake of every worker a call."""
    c = np.empty(1, np.int64)
    c[0] = 0
    return c
