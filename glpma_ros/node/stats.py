"""Statistics of the node: counters since start, distributions over a recent window, and the
throttle that keeps a flood of equal log lines down to one a second."""
from __future__ import annotations

import math
import time
from collections import Counter, deque

import numpy as np

#: statistics cover the most recent inputs
WINDOW = 2000
#: distinct rejection reasons shown on /diagnostics (the rest are counted as "other")
MAX_REASONS = 16
#: seconds between two log lines of the same rejection reason
LOG_THROTTLE_S = 1.0


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


def percentiles_ms(samples) -> tuple[float, float, float]:
    if not samples:
        return (math.nan, math.nan, math.nan)
    arr = np.fromiter(samples, dtype=float) * 1e3
    p50, p99 = np.percentile(arr, [50, 99])
    return float(p50), float(p99), float(arr.max())


class Statistics:
    """Counters since start, and distributions over the last :data:`WINDOW` inputs.
    ``handled`` inputs went through :meth:`FkService.handle`; ``dropped`` ones were replaced
    by a newer input first; received = handled + dropped."""

    def __init__(self):
        self.handled = self.published = self.rejected = self.dropped = self.deadline_misses = 0
        self.dropped_reported = 0     # dropped count at the last diagnostics report
        self.reasons: Counter = Counter()
        # ~/request_assembly_modes: requests taken, answered, failed, merged into a later one
        self.modes_requests = self.modes_published = self.modes_failed = self.modes_coalesced = 0
        self.modes_last = ""
        self.modes_last_starts = 0
        self.modes_last_failure = ""
        self.starts: Counter = Counter()
        self.solve_s: deque = deque(maxlen=WINDOW)
        self.latency_s: deque = deque(maxlen=WINDOW)
        self.evaluations: deque = deque(maxlen=WINDOW)
        self.residual_m: deque = deque(maxlen=WINDOW)
        self.conditioning: deque = deque(maxlen=WINDOW)
        self.extras_s: deque = deque(maxlen=WINDOW)   # TF, covariance, twist, markers of a pose
        self.extras_handoff_s: deque = deque(maxlen=WINDOW)   # the solving thread's part of them
        self.extras_dropped = 0       # poses whose extra outputs the extras thread never caught up with
        self.capped_reported = 0      # covariances capped at a singularity, at the last report
        self.last_estimate = None
        self.last_reason = ""
        self.period = Counter()       # events since the last diagnostics report

    def count_reason(self, key: str) -> None:
        if key not in self.reasons and len(self.reasons) >= MAX_REASONS:
            key = "other"
        self.reasons[key] += 1
