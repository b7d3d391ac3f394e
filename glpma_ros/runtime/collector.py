"""Python's cyclic garbage collector held off while a solve runs under a deadline.

The collector runs whenever enough container objects have been allocated, at whatever Python line
allocates the next one: inside a solve, between two compiled calls, where the deadline's clock checks
cannot see it coming.  One such collection pauses the thread for 0.1-0.7 ms (measured on the bench's
2-core machine, a young generation's collection in a process with Numba and SciPy loaded): more than a
compiled call's time, so a solve that checked its clock in time still returned that much late.

:data:`HOLD` (``with HOLD:``) disables the collector for the duration of a solve and enables it again
afterwards if it was enabled before; the garbage of the solve is collected after it returns, on the
caller's time (the node's time between two inputs).  Nested holds (the Estimator around its solvers)
and holds on several threads at once keep the collector off until the last one ends."""
from __future__ import annotations

import gc
import threading


class CollectorHold:
    """A context manager that keeps the cyclic garbage collector disabled while any holder is inside it."""

    def __init__(self):
        self._lock = threading.Lock()
        self._holders = 0
        self._was_enabled = False

    def __enter__(self):
        with self._lock:
            if self._holders == 0:
                self._was_enabled = gc.isenabled()
                gc.disable()
            self._holders += 1
        return self

    def __exit__(self, *exc):
        with self._lock:
            self._holders -= 1
            if self._holders == 0 and self._was_enabled:
                gc.enable()
        return False


#: the one hold every solve under a deadline takes (the collector is one per process)
HOLD = CollectorHold()
