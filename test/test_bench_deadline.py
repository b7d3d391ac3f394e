"""The deadline section's accounting of disturbed solves: a call off its core (its wall time over its
thread's CPU time) is flagged by the timed calls, and the section's undisturbed figures leave out the
preempted, off-core and collected solves.  No wall-clock figure is asserted."""
import time
from collections import Counter
from types import SimpleNamespace

import numpy as np

from glpma_tools import timing
from glpma_tools.bench.timing import DISTURBED, deadline_section, disturbed

#: a call that waits this long (s) is off its core for it: many times the off-core threshold
WAIT_S = 40 * timing.OFF_CORE_S
#: the overruns (ms) of the synthetic cell: one per kind of disturbance, then solves on time
OVERRUNS_MS = np.array([30.0, 20.0, 10.0, 0.05, 0.02, -0.5])


def test_a_call_that_waits_is_off_its_core_or_preempted():
    """A sleeping call runs on no core: the timed calls flag it off its core (or preempted, when the
    scheduler's wake-up counted as an involuntary switch)."""
    calls = timing.timed_calls(lambda _: time.sleep(WAIT_S), 3, budget_ms=1.0, stop_early=False)
    assert calls.off_core.shape == (3,)
    assert np.all(calls.off_core | calls.preempted), (calls.off_core, calls.preempted)
    assert not np.any(calls.off_core & calls.preempted)            # counted once


def _row(**flags):
    n = len(OVERRUNS_MS)
    masks = {k: np.zeros(n, dtype=bool) for k in ("preempted", "off_core", "collected")}
    for k, i in flags.items():
        masks[k][i] = True
    budget_ms = 1.0
    return SimpleNamespace(case="3-RPR, legs without an assembly", solver="g3pcx", load="no load added",
                           budget_ms=budget_ms, elapsed_s=(OVERRUNS_MS + budget_ms) / 1e3,
                           overrun_ms=OVERRUNS_MS, statuses=Counter(budget_exhausted=n), **masks)


def test_the_undisturbed_figures_leave_out_preempted_off_core_and_collected_solves():
    row = _row(preempted=0, off_core=1, collected=2)
    assert disturbed(row).tolist() == [True, True, True, False, False, False]
    text = "\n".join(deadline_section({"deadline": [row], "figures": {}}, "BENCHMARKS.md"))
    # per solver and per cell: all of them (p99.9 interpolated between the two largest), the counts, and the
    # worst undisturbed overrun (+0.05 ms)
    assert f"| {DISTURBED} |" in text
    assert "| g3pcx | no load added | 6 | +29.950 / +30.000 | 1 / 1 / 1 | +0.050 / +0.050 |" in text, text
    assert "3 solves were disturbed" in text and "Late undisturbed" not in text, text
