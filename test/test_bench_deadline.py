"""The deadline section's accounting of disturbed solves: a call off its core (its wall time over its
thread's CPU time) is flagged by the timed calls, and the section's undisturbed figures leave out the
preempted, off-core and collected solves; a late solve's lateness is split into its time off its core and
its CPU time past the budget.  No wall-clock figure is asserted."""
import time
from collections import Counter
from types import SimpleNamespace

import numpy as np

from glpma_tools import timing
from glpma_tools.bench.timing import (
    CPU_PAST,
    DISTURBED,
    LATE_MS,
    OFF_CORE,
    RAN_PAST,
    deadline_section,
    disturbed,
    late_solves,
)

#: a call that waits this long (s) is off its core for it: many times the off-core threshold
WAIT_S = 40 * timing.OFF_CORE_S
#: the overruns (ms) of the synthetic cell: one per kind of disturbance, then solves on time
OVERRUNS_MS = np.array([30.0, 20.0, 10.0, 0.05, 0.02, -0.5])


def test_a_call_that_waits_is_off_its_core_or_preempted():
    """A sleeping call runs on no core: the timed calls flag it off its core (or preempted, when the
    scheduler's wake-up counted as an involuntary switch)."""
    calls = timing.timed_calls(lambda _: time.sleep(WAIT_S), 3, budget_ms=1.0, stop_early=False)
    assert calls.off_core.shape == (3,)
    # the CPU time is measured per call, and a sleep is mostly off the core
    assert calls.cpu_s.shape == (3,) and np.all(calls.cpu_s < calls.elapsed_s), (calls.cpu_s, calls.elapsed_s)
    assert np.all(calls.off_core | calls.preempted), (calls.off_core, calls.preempted)
    assert not np.any(calls.off_core & calls.preempted)            # counted once


def _row(cpu_ms=None, **flags):
    n = len(OVERRUNS_MS)
    masks = {k: np.zeros(n, dtype=bool) for k in ("preempted", "off_core", "collected")}
    for k, i in flags.items():
        masks[k][i] = True
    budget_ms = 1.0
    return SimpleNamespace(case="3-RPR, legs without an assembly", solver="g3pcx", load="no load added",
                           budget_ms=budget_ms, elapsed_s=(OVERRUNS_MS + budget_ms) / 1e3,
                           overrun_ms=OVERRUNS_MS, statuses=Counter(budget_exhausted=n), **masks,
                           **({} if cpu_ms is None else {"cpu_s": np.asarray(cpu_ms) / 1e3}))


def test_the_undisturbed_figures_leave_out_preempted_off_core_and_collected_solves():
    row = _row(preempted=0, off_core=1, collected=2)
    assert disturbed(row).tolist() == [True, True, True, False, False, False]
    text = "\n".join(deadline_section({"deadline": [row], "figures": {}}, "BENCHMARKS.md"))
    # per solver and per cell: all of them (p99.9 interpolated between the two largest), the counts, and the
    # worst undisturbed overrun (+0.05 ms)
    assert f"| {DISTURBED} |" in text and f"| {CPU_PAST} |" in text
    # no CPU time measured: the CPU column is dashes
    assert "| g3pcx | no load added | 6 | +29.950 / +30.000 | 1 / 1 / 1 | +0.050 / +0.050 | — / — |" in text, text
    assert "3 solves were disturbed" in text and "Late undisturbed" not in text, text


def test_a_late_solve_is_split_into_time_off_its_core_and_cpu_past_the_budget():
    """The first solve (30 ms late) used 1 ms of CPU for its 1 ms budget: off its core for 30 ms, the OS's doing;
    the second (20 ms late) used 20.5 ms of CPU: on its core past the deadline; the third (10 ms late) 1.05 ms of
    CPU (0.05 ms past the budget, within LATE_MS): off its core.  The rest are within LATE_MS of the deadline: not
    listed."""
    row = _row(cpu_ms=[1.0, 20.5, 1.05, 1.0, 1.0, 0.5])
    late = late_solves([row])
    assert [line[4] for line in late] == ["+30.000", "+20.000", "+10.000"]          # the latest first
    assert [line[-1] for line in late] == [OFF_CORE, RAN_PAST, OFF_CORE]
    assert late[0][5] == "30.000" and late[1][6] == "+19.500", late    # wall less CPU; CPU less the budget
    assert 0.05 < LATE_MS                                               # the third's CPU past is within it
    text = "\n".join(deadline_section({"deadline": [row], "figures": {}}, "BENCHMARKS.md"))
    # the CPU column's max, per solver and per cell; the late table
    assert text.count("/ +19.500 |") == 2 and f"| {RAN_PAST} |" in text, text
