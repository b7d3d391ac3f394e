"""Redundant legs on ``/diagnostics``: inputs whose legs were inconsistent, the leg left out of the
published pose, and the legs that have failed.

A leg named at fault (``inconsistent_legs``, :mod:`glpma_ros.estimation.redundancy`) on :data:`FAILED_AFTER`
inputs in a row is reported as failed (level WARN) until it agrees again: an input whose legs are all
consistent (status ``converged``) clears every failure.  Only for a config with redundant legs: with
exactly as many legs as degrees of freedom nothing is added to the report.
"""
from __future__ import annotations

import threading
from collections import Counter

from ..estimation.estimator import STATUS_CONVERGED, STATUS_INCONSISTENT

#: consecutive inputs naming the same leg at fault before it is reported as failed (a single
#: inconsistent input is a false alarm in 1 - CONSISTENCY_LEVEL of a healthy manipulator's inputs)
FAILED_AFTER = 10


class LegHealth:
    """Per-leg fault bookkeeping of the node, with a lock of its own: the solving thread notes each
    estimate, the report thread (:class:`~glpma_ros.node.loops.ReportLoop`) copies the state under the
    lock and formats it after."""

    def __init__(self, model):
        self.active = model.redundancy > 0
        self.inconsistent = 0            # inputs with status inconsistent_legs
        self.left_out: Counter = Counter()   # leg -> published poses that left it out
        self.streak = [0] * model.n_legs     # consecutive inconsistent inputs naming each leg
        self.failed: set = set()
        self.last_left_out = None
        self.last_message = ""
        self._period = 0                 # inconsistent inputs since the last report
        self._lock = threading.Lock()

    def note(self, estimate) -> None:
        """Account for one estimate (any status)."""
        if not self.active or estimate is None:
            return
        with self._lock:
            self._note(estimate)

    def _note(self, estimate) -> None:
        if estimate.status == STATUS_INCONSISTENT:
            self.inconsistent += 1
            self._period += 1
            self.last_message = estimate.message
            leg = estimate.suspect_leg
            for i in range(len(self.streak)):
                self.streak[i] = self.streak[i] + 1 if i == leg else 0
            if leg is not None and self.streak[leg] >= FAILED_AFTER:
                self.failed.add(leg)
            self.last_left_out = estimate.excluded_leg
            if estimate.excluded_leg is not None:
                self.left_out[estimate.excluded_leg] += 1
        elif estimate.status == STATUS_CONVERGED:     # every leg agrees
            self.streak = [0] * len(self.streak)
            self.failed.clear()
            self.last_left_out = None

    def report(self, names) -> tuple[list, list]:
        """``(key-value pairs, problems)`` for /diagnostics, legs called by ``names`` (the joint names, leg
        order); starts a new period."""
        if not self.active:
            return [], []
        with self._lock:                 # a copy: formatting happens after, holding nothing
            period, self._period = self._period, 0
            inconsistent, last_left_out, last_message = self.inconsistent, self.last_left_out, self.last_message
            failed_legs, left_out = sorted(self.failed), sorted(self.left_out.items())
        failed = ", ".join(names[i] for i in failed_legs) or "none"
        values = [("inputs with inconsistent legs", inconsistent),
                  ("leg left out last", "none" if last_left_out is None else names[last_left_out]),
                  ("legs left out", ", ".join(f"{names[i]}: {n}" for i, n in left_out) or "none"),
                  ("failed legs", failed)]
        if last_message:
            values.append(("last inconsistency", last_message))
        problems = []
        if failed_legs:
            problems.append(f"failed leg{'s' if len(failed_legs) > 1 else ''} {failed} (named at fault on "
                            f"{FAILED_AFTER}+ inputs in a row)")
        if period:
            problems.append(f"{period} inputs with inconsistent legs")
        return values, problems
