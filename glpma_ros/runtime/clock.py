"""The clock the compiled kernels read, so that a kernel stops at a deadline *inside* its loop.

A compiled call of a solver (a chunk of generations) can only be stopped between two calls from Python,
and one call into a kernel that draws from a ``numpy.random.Generator`` costs some 20 µs before any work
(Numba unboxes the generator's bit generator at each call): calls short enough to stop within a few
microseconds of a deadline would spend most of their time being called.  So the kernels read the clock
themselves, between two steps of their loop (a child of a generation, a generation of G3-PCX), and stop
there.  The clock is ``CLOCK_MONOTONIC`` through ``clock_gettime`` (the vDSO, no system call: about 0.1 µs
on this machine), the clock ``time.perf_counter`` reads on Linux.

The deadline is handed to a kernel as its end on the kernel's clock (:func:`kernel_end`), computed
before the call from the caller's ``time.perf_counter`` deadline: the time left, read on the caller's clock
just before the call, added to ``time.monotonic()`` (Python's read of the same ``CLOCK_MONOTONIC``).  So
the end does not move by the time the call takes to start (the 20 µs above), and a caller that measures
time by another clock (the tests' fake clock) still bounds the kernel's work by its own measure of the
time left.  ``math.inf``: no deadline, and the kernel never reads the clock.
"""
from __future__ import annotations

import math
import time

from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

#: the clock ``time.perf_counter`` and ``time.monotonic`` read on Linux (Python's own constant for it, compiled
#: into the kernels)
CLOCK_ID = time.CLOCK_MONOTONIC
#: nanoseconds per second (``struct timespec`` counts seconds and nanoseconds)
NS_PER_S = 1e9


def clock_reader(clock_id: int):
    """A compiled ``clock_gettime(clock_id)`` in seconds, as a float: an intrinsic for kernels (``CLOCK_ID``
    here; a tool's probe also reads the thread's CPU clock, ``time.CLOCK_THREAD_CPUTIME_ID``)."""

    @intrinsic
    def read_s(typingctx):
        def codegen(context, builder, signature, args):
            i32, i64, f64 = ir.IntType(32), ir.IntType(64), ir.DoubleType()
            timespec = ir.LiteralStructType([i64, i64])           # tv_sec, tv_nsec (64-bit Linux and macOS)
            clock_gettime = cgutils.get_or_insert_function(builder.module,
                                                           ir.FunctionType(i32, [i32, timespec.as_pointer()]),
                                                           "clock_gettime")
            ts = cgutils.alloca_once(builder, timespec)
            builder.call(clock_gettime, [ir.Constant(i32, clock_id), ts])
            sec = builder.sitofp(builder.load(cgutils.gep_inbounds(builder, ts, 0, 0)), f64)
            nsec = builder.sitofp(builder.load(cgutils.gep_inbounds(builder, ts, 0, 1)), f64)
            return builder.fadd(sec, builder.fdiv(nsec, ir.Constant(f64, NS_PER_S)))

        return types.float64(), codegen
    return read_s


#: ``clock_gettime(CLOCK_ID)`` in seconds, compiled into the kernels
_monotonic_s = clock_reader(CLOCK_ID)


@njit(cache=True)
def monotonic_s():
    """The kernels' clock, in seconds (callable from Python too)."""
    return _monotonic_s()


@njit(cache=True)
def reached(end):
    """True once the kernels' clock is at ``end`` (never reads the clock when ``end`` is ``inf``)."""
    return end != math.inf and _monotonic_s() >= end


def kernel_end(deadline) -> float:
    """``deadline`` (a ``time.perf_counter`` value; None: no deadline) on the kernels' clock: what a kernel
    is handed (``inf``: never)."""
    if deadline is None:
        return math.inf
    return time.monotonic() + (deadline - time.perf_counter())
