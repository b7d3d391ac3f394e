"""The clock the compiled kernels read, so that a kernel stops at a deadline *inside* its loop.

A compiled call of a solver (a chunk of generations) can only be stopped between two calls from Python,
and one call into a kernel that draws from a ``numpy.random.Generator`` costs some 20 µs before any work
(Numba unboxes the generator's bit generator at each call): calls short enough to stop within a few
microseconds of a deadline would spend most of their time being called.  So the kernels read the clock
themselves, between two steps of their loop (a child of a generation, a generation of G3-PCX), and stop
there.  The clock is ``CLOCK_MONOTONIC`` through ``clock_gettime`` (the vDSO: tens of nanoseconds, no
system call), the clock ``time.perf_counter`` reads on Linux.

The deadline is handed to a kernel as the time left (:func:`time_left`, measured by the caller's
``time.perf_counter``), from which the kernel sets its own end on its own clock when it starts
(:func:`end_after`): no assumption that the two clocks share an origin, and a caller that measures
time by another clock (the tests' fake clock) still bounds the kernel's work by its own measure of the
time left.  ``math.inf`` left: no deadline, and the kernel never reads the clock.
"""
from __future__ import annotations

import math
import time

from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

#: the clock ``time.perf_counter`` reads on Linux (Python's own constant for it, compiled into the kernels)
CLOCK_ID = time.CLOCK_MONOTONIC
#: nanoseconds per second (``struct timespec`` counts seconds and nanoseconds)
NS_PER_S = 1e9


@intrinsic
def _monotonic_s(typingctx):
    """``clock_gettime(CLOCK_ID)`` in seconds, as a float."""

    def codegen(context, builder, signature, args):
        i32, i64, f64 = ir.IntType(32), ir.IntType(64), ir.DoubleType()
        timespec = ir.LiteralStructType([i64, i64])           # tv_sec, tv_nsec (64-bit Linux and macOS)
        clock_gettime = cgutils.get_or_insert_function(builder.module,
                                                       ir.FunctionType(i32, [i32, timespec.as_pointer()]),
                                                       "clock_gettime")
        ts = cgutils.alloca_once(builder, timespec)
        builder.call(clock_gettime, [ir.Constant(i32, CLOCK_ID), ts])
        sec = builder.sitofp(builder.load(cgutils.gep_inbounds(builder, ts, 0, 0)), f64)
        nsec = builder.sitofp(builder.load(cgutils.gep_inbounds(builder, ts, 0, 1)), f64)
        return builder.fadd(sec, builder.fdiv(nsec, ir.Constant(f64, NS_PER_S)))

    return types.float64(), codegen


@njit(cache=True)
def monotonic_s():
    """The kernels' clock, in seconds (callable from Python too)."""
    return _monotonic_s()


@njit(cache=True)
def end_after(left_s):
    """The kernels' clock ``left_s`` seconds from now (``inf``: never)."""
    if left_s == math.inf:
        return math.inf
    return _monotonic_s() + left_s


@njit(cache=True)
def reached(end):
    """True once the kernels' clock is at ``end`` (never reads the clock when ``end`` is ``inf``)."""
    return end != math.inf and _monotonic_s() >= end


def time_left(deadline) -> float:
    """Seconds from now (``time.perf_counter``) to ``deadline`` (a ``time.perf_counter`` value; None: no
    deadline, ``inf``), at least 0: what a kernel is handed."""
    if deadline is None:
        return math.inf
    return max(deadline - time.perf_counter(), 0.0)
