"""Statistics of the node: counters since start, distributions over a recent window, and the
throttle that keeps a flood of equal log lines down to one a second.

Recording and reporting are kept apart so that a report never delays an input.  Each input
updates :class:`Statistics` in O(1) (counters, and one slot of a ring buffer per distribution)
under the statistics' own lock, held for about a microsecond; a report takes a
:class:`StatsSnapshot` -- the counters under the same lock, then copies of the ring buffers --
and puts them in order and computes its percentiles afterwards, outside every lock.
"""
from __future__ import annotations

import math
import threading
import time
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

#: statistics cover the most recent inputs
WINDOW = 2000
#: distinct rejection reasons shown on /diagnostics (the rest are counted as "other")
MAX_REASONS = 16
#: seconds between two log lines of the same rejection reason
LOG_THROTTLE_S = 1.0
#: the percentiles /diagnostics shows (median and the tail), besides the maximum
P50, P99 = 0.50, 0.99


class LogThrottle:
    """Lets one log line per key through every ``period_s`` and counts the rest."""

    def __init__(self, period_s: float = LOG_THROTTLE_S, clock=time.monotonic):
        self.period_s = period_s
        self.clock = clock
        self._last: dict = {}
        self._suppressed: Counter = Counter()

    def __call__(self, key) -> int | None:
        """``None`` to stay silent, else the number of lines suppressed since the last one."""
        now = self.clock()
        last = self._last.get(key)
        if last is not None and now - last < self.period_s:
            self._suppressed[key] += 1
            return None
        self._last[key] = now
        return self._suppressed.pop(key, 0)


def _quantile_sorted(s: np.ndarray, q: float) -> float:
    """The ``q`` quantile of the sorted ``s`` by linear interpolation between the closest ranks
    (NumPy's default ``percentile`` method, Hyndman & Fan 1996, definition 7)."""
    pos = q * (s.size - 1)
    lo = math.floor(pos)
    hi = min(lo + 1, s.size - 1)
    return float(s[lo] + (pos - lo) * (s[hi] - s[lo]))


def percentiles_ms(samples) -> tuple[float, float, float]:
    """p50, p99 and maximum of ``samples`` (seconds) in milliseconds; NaN when there are none.
    One sort (NumPy's, without the interpreter's lock) and three look-ups, rather than
    ``numpy.percentile``'s generic path, which is mostly Python."""
    s = np.sort(np.asarray(samples, dtype=float))
    if s.size == 0:
        return (math.nan, math.nan, math.nan)
    return _quantile_sorted(s, P50) * 1e3, _quantile_sorted(s, P99) * 1e3, float(s[-1]) * 1e3


class Window:
    """The last ``size`` values of one quantity: a ring buffer over a preallocated array, so that
    adding a value costs the same whatever came before (no allocation, no shifting)."""

    def __init__(self, size: int = WINDOW):
        self._values = np.zeros(size)
        self._count = 0

    def append(self, value: float) -> None:
        self._values[self._count % self._values.size] = value
        self._count += 1

    def __len__(self) -> int:
        return min(self._count, self._values.size)

    def values(self) -> np.ndarray:
        """A copy of the values in the window, oldest first."""
        return self.in_order(*self.copy())

    def copy(self) -> tuple[np.ndarray, int]:
        """``(buffer, count)``: a copy of the buffer as it is and the number of values added so far
        (one memory copy: what a snapshot takes under the lock)."""
        return self._values.copy(), self._count

    @staticmethod
    def in_order(buffer: np.ndarray, count: int) -> np.ndarray:
        """The values of a :meth:`copy`, oldest first."""
        if count <= buffer.size:
            return buffer[:count]
        start = count % buffer.size
        return np.concatenate((buffer[start:], buffer[:start]))

    def last(self) -> float:
        """The newest value (NaN when there is none)."""
        return float(self._values[(self._count - 1) % self._values.size]) if self._count else math.nan


#: the distributions kept over the last WINDOW inputs (seconds unless named otherwise)
WINDOWS = ("solve_s", "latency_s", "evaluations", "residual_m", "conditioning",
           "extras_s",             # TF, covariance, twist, markers of a pose, in the extras thread
           "extras_handoff_s")     # the solving thread's part of them


@dataclass(frozen=True)
class StatsSnapshot:
    """The statistics at one moment: counters since start, the events of the reporting period
    that ended with it (``period``), and a copy of each window (name -> array)."""

    handled: int
    published: int
    rejected: int
    dropped: int
    deadline_misses: int
    extras_dropped: int
    starts: dict
    reasons: list               # [(reason, count)], most frequent first
    last_estimate: object
    last_reason: str
    period: dict
    raw_windows: dict = field(repr=False)     # name -> Window.copy()

    def window(self, name: str) -> np.ndarray:
        """The values of window ``name`` (one of :data:`WINDOWS`), oldest first."""
        return Window.in_order(*self.raw_windows[name])

    @property
    def received(self) -> int:
        return self.handled + self.dropped


class Statistics:
    """Counters since start, and distributions over the last :data:`WINDOW` inputs.
    ``handled`` inputs went through :meth:`FkService.handle`; ``dropped`` ones were replaced
    by a newer input first; received = handled + dropped.

    Every ``record_*`` method is O(1) and may be called from any thread; :meth:`snapshot`
    copies what a report needs.  The attributes are for reading."""

    def __init__(self, window: int = WINDOW):
        self._lock = threading.Lock()
        self.handled = self.published = self.rejected = self.dropped = self.deadline_misses = 0
        self.extras_dropped = 0       # poses whose extra outputs the extras thread never caught up with
        self.reasons: Counter = Counter()
        self.starts: Counter = Counter()
        self.last_estimate = None
        self.last_reason = ""
        self._period: Counter = Counter()       # events since the last report
        for name in WINDOWS:
            setattr(self, name, Window(window))

    # -- the solving thread ------------------------------------------------------------------
    def record_handled(self) -> None:
        with self._lock:
            self.handled += 1

    def record_estimate(self, estimate) -> None:
        """An estimate the estimator returned, converged or not."""
        with self._lock:
            self.last_estimate = estimate
            self.starts[estimate.start] += 1
            self.solve_s.append(estimate.elapsed_s)
            self.evaluations.append(estimate.evaluations)

    def record_published(self, conditioning: float, residual_m: float) -> None:
        with self._lock:
            self.published += 1
            self.conditioning.append(conditioning)
            self.residual_m.append(residual_m)

    def record_rejected(self, key: str, reason: str) -> None:
        """A rejected input: ``key`` counts it among the reasons, ``reason`` is its full text."""
        with self._lock:
            self.rejected += 1
            self._period["rejected"] += 1
            if key not in self.reasons and len(self.reasons) >= MAX_REASONS:
                key = "other"
            self.reasons[key] += 1
            self.last_reason = reason

    def record_latency(self, latency_s: float, missed: bool) -> None:
        with self._lock:
            self.latency_s.append(latency_s)
            if missed:
                self.deadline_misses += 1
                self._period["deadline_misses"] += 1

    def record_extras_handoff(self, seconds: float) -> None:
        with self._lock:
            self.extras_handoff_s.append(seconds)

    # -- the transport's and the extras threads ----------------------------------------------
    def record_dropped(self, count: int) -> None:
        with self._lock:
            self.dropped += count
            self._period["dropped"] += count

    def record_extras_time(self, seconds: float) -> None:
        with self._lock:
            self.extras_s.append(seconds)

    def record_extras_dropped(self, count: int) -> None:
        with self._lock:
            self.extras_dropped += count

    # -- reports -----------------------------------------------------------------------------
    def snapshot(self, new_period: bool = False, pause=lambda: None) -> StatsSnapshot:
        """Everything a report needs, copied (the counters under the lock, about a microsecond;
        the windows and the record after it); with ``new_period`` the events of the period are handed over and a new
        period starts; ``pause()`` runs between the counters and the windows."""
        with self._lock:
            counts = (self.handled, self.published, self.rejected, self.dropped, self.deadline_misses,
                      self.extras_dropped, dict(self.starts), dict(self.reasons), self.last_estimate,
                      self.last_reason, dict(self._period))
            if new_period:
                self._period.clear()
        pause()
        # the windows are copied after the lock is released (each copy is one call that the
        # interpreter runs whole, so it sees every append whole): they may hold the input being
        # recorded meanwhile, which the counters above do not yet count
        raw = [getattr(self, name).copy() for name in WINDOWS]
        *head, starts, reasons, last_estimate, last_reason, period = counts
        return StatsSnapshot(*head, starts, Counter(reasons).most_common(), last_estimate, last_reason, period,
                             dict(zip(WINDOWS, raw)))
