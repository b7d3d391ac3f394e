"""Python's cyclic garbage collector held off while a solve runs under a deadline.

The collector runs whenever enough container objects have been allocated, at whatever Python line
allocates the next one: inside a solve, between two compiled calls, where the deadline's clock checks
cannot see it coming.  One such collection pauses the thread for 0.1-0.7 ms (measured on the bench's
2-core machine, a young generation's collection in a process with Numba and SciPy loaded): more than a
compiled call's time, so a solve that checked its clock in time still returned that much late.

:data:`HOLD` disables the collector for the duration of a solve (``HOLD.acquire()``, then
``HOLD.release()`` in a ``finally``) and enables it again afterwards if it was enabled before; the garbage
of the solve is collected after it returns, on the caller's time (the node's time between two inputs).
Nested holds (the Estimator around its solvers) and holds on several threads at once keep the collector
off until the last one ends.  ``acquire`` allocates no object before the collector is off (a ``with``
statement would: its bound ``__enter__`` and ``__exit__``, and an allocation can start a collection)."""
from __future__ import annotations

import gc
import threading


class CollectorHold:
    """Keeps the cyclic garbage collector disabled while any holder holds it."""

    def __init__(self):
        self._lock = threading.Lock()
        self._holders = 0
        self._was_enabled = False

    def acquire(self) -> None:
        """Hold the collector off (every call is matched by one :meth:`release`)."""
        self._lock.acquire()
        if self._holders == 0:
            self._was_enabled = gc.isenabled()
            gc.disable()
        self._holders += 1
        self._lock.release()

    def release(self) -> None:
        """End one hold; the last one restores the collector as the first found it."""
        self._lock.acquire()
        self._holders -= 1
        if self._holders == 0 and self._was_enabled:
            gc.enable()
        self._lock.release()


#: the one hold every solve under a deadline takes (the collector is one per process)
HOLD = CollectorHold()
