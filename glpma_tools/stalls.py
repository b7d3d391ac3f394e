"""The machine's own stalls: how long a thread that does nothing but read the clock loses it, under the
same load as the solves it is measured beside (the deadline section of ``glpma-fk bench``).

What ``cyclictest`` and the kernel's ``osnoise`` tracer measure, from a process: a compiled loop reads
``CLOCK_MONOTONIC`` (the clock the solvers' deadlines are on) back to back; wherever two reads are more than
``threshold_s`` apart the thread did not run for that long, and the loop records the gap with the thread's
CPU time across it (``CLOCK_THREAD_CPUTIME_ID``).  A gap the thread's CPU clock did not count (by more than
:data:`~glpma_tools.timing.OFF_CORE_S`, the timed calls' criterion) was spent **off its core**: another
process ran, or the hypervisor ran another virtual machine (a kernel with steal-time accounting leaves that
out of the thread's time).  A gap it counted was **on its core** but not in the loop: interrupts served
there (a kernel built without ``CONFIG_IRQ_TIME_ACCOUNTING`` bills them to the interrupted thread) or the
hypervisor handling an exit of the virtual CPU.  No code running in that thread can be faster than these
gaps: a solve that meets one ends late by about its length, whatever the solver does.

The loop runs in bursts as the deadline cells do (``burst_s`` of spinning, ``rest_s`` of sleep: a
``SCHED_FIFO`` thread that never sleeps is throttled by the kernel), and allocates nothing while it spins.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from glpma_ros.runtime.clock import clock_reader, monotonic_s

from .timing import OFF_CORE_S

#: a gap between two clock reads longer than this (s) is recorded: the loop's own iteration is ~0.1 µs, and about
#: a microsecond when it also reads the thread's CPU clock
THRESHOLD_S = 20e-6
#: the loop reads the thread's CPU clock again every this many iterations: that read is a system call (the
#: monotonic clock's is not: the vDSO), so that the thread's CPU time before a gap is a recent one
CPU_READ_STRIDE = 64

#: the thread's CPU clock, compiled as the kernels' monotonic one is (:func:`~glpma_ros.runtime.clock.monotonic_s`)
_thread_cpu_s = clock_reader(time.CLOCK_THREAD_CPUTIME_ID)


@njit(cache=True)
def spin_and_record(seconds, threshold_s, gaps):
    """Read the monotonic clock back to back for ``seconds``; each gap over ``threshold_s`` goes to a row of
    ``gaps``: (its start from the loop's start, its length, the thread's CPU time across it), in seconds.
    Returns the gaps seen (rows past ``gaps``' end are not written: :func:`probe` sizes it for every gap a burst
    can hold)."""
    start = monotonic_s()
    cpu_before = _thread_cpu_s()
    previous = start
    seen = 0
    reads = 0
    while True:
        now = monotonic_s()
        reads += 1
        if now - previous > threshold_s:
            cpu = _thread_cpu_s()
            if seen < gaps.shape[0]:
                gaps[seen, 0] = previous - start
                gaps[seen, 1] = now - previous
                gaps[seen, 2] = cpu - cpu_before
            seen += 1
            cpu_before = cpu
        elif reads % CPU_READ_STRIDE == 0:
            cpu_before = _thread_cpu_s()
        # the next gap is measured from this read, across the CPU clock's read: that read is a system call, and
        # a thread is most often taken off its core on the way out of one (a gap the loop must not skip)
        previous = now
        if now - start >= seconds:
            return seen


@njit(cache=True)
def spin_until(seconds):
    """Read the clock until ``seconds`` have passed since this call's first read, then return: a solver that does
    no work but stop at its deadline, the floor the deadline section sets beside the solvers (it ends late only by
    a stall of the machine's that its deadline falls in, and by its own entry and return, microseconds)."""
    start = monotonic_s()
    while monotonic_s() - start < seconds:
        pass
    return seconds


#: the deadline section's name for :func:`spin_until` among the solvers
CLOCK_ONLY = "clock only"


def clock_only(budget_s: float) -> str:
    """:func:`spin_until` as a deadline cell's call: the status of a solve that ran to its deadline."""
    spin_until(budget_s)
    return "budget_exhausted"


@dataclass
class Stalls:
    """The gaps a probe recorded: ``seconds`` spun in all, and per gap its length and the thread's CPU time
    across it (s)."""

    seconds: float
    wall_s: np.ndarray
    cpu_s: np.ndarray

    @classmethod
    def joined(cls, parts) -> "Stalls":
        """The probes ``parts`` as one (a probe spread over the cells of a load)."""
        parts = list(parts)
        return cls(sum(p.seconds for p in parts), np.concatenate([p.wall_s for p in parts] or [np.zeros(0)]),
                   np.concatenate([p.cpu_s for p in parts] or [np.zeros(0)]))

    @property
    def off_core(self) -> np.ndarray:
        """Per gap: the thread's CPU clock did not count it (another process or the hypervisor had the core)."""
        return self.wall_s - self.cpu_s > OFF_CORE_S

    def over(self, ms: float, on_core: bool | None = None) -> int:
        """Gaps longer than ``ms``; only those on (True) or off (False) its core when ``on_core`` is given."""
        sel = self.wall_s * 1e3 > ms
        if on_core is not None:
            sel &= ~self.off_core if on_core else self.off_core
        return int(np.sum(sel))

    def share_past(self, ms: float) -> float:
        """The share of the time probed at which a deadline falling then is passed by more than ``ms`` because of a
        stall: a stall of length L leaves its last (L - ms) in that state.  A solve that runs to its deadline, at
        an instant the stalls do not know of, ends more than ``ms`` late with about this probability."""
        return float(np.sum(np.maximum(self.wall_s * 1e3 - ms, 0.0))) / 1e3 / self.seconds if self.seconds > 0 \
            else float("nan")

    def longest_ms(self, on_core: bool | None = None) -> float:
        """The longest gap (ms; 0 when none), of those on or off its core when ``on_core`` is given."""
        sel = np.ones(self.wall_s.shape, dtype=bool) if on_core is None else (
            ~self.off_core if on_core else self.off_core)
        return float(np.max(self.wall_s[sel], initial=0.0)) * 1e3


def probe(seconds: float, burst_s: float, rest_s: float = 0.0, threshold_s: float = THRESHOLD_S) -> Stalls:
    """Spin for ``seconds`` in all, in bursts of ``burst_s`` each after ``rest_s`` of sleep, on the calling
    thread (under its scheduling policy and affinity), and return the gaps recorded."""
    # every gap but the last is longer than threshold_s and began within the burst: this many rows hold them all
    gaps = np.empty((int(burst_s / threshold_s) + 2, 3))
    spin_and_record(min(burst_s, 1e-3), threshold_s, gaps)      # compiled (or loaded) before it counts
    walls, cpus, spun = [], [], 0.0
    while spun < seconds:
        if rest_s:
            time.sleep(rest_s)
        burst = min(burst_s, seconds - spun)
        seen = spin_and_record(burst, threshold_s, gaps)
        walls.append(gaps[:seen, 1].copy())
        cpus.append(gaps[:seen, 2].copy())
        spun += burst
    return Stalls(spun, np.concatenate(walls), np.concatenate(cpus))
