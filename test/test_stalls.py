"""The machine's stall probe (glpma_tools.stalls) and its table in the deadline section: a real process
sharing the probe's core makes gaps the probe records off its core; the accounting of gaps, and the section's
row per load.  No figure of this machine's stalls is asserted."""
import multiprocessing
import os
import time
from types import SimpleNamespace

import numpy as np
import pytest

from glpma_tools import stalls, timing
from glpma_tools.bench.timing import STALLS_HEAD, deadline_section, stalls_cells

#: seconds the probe spins beside the competing process: many of the scheduler's time slices (a few ms each)
SHARED_SECONDS = 0.3
#: a gap that long (ms) is a time slice of the other process, not the loop's own iteration (~0.1 µs) nor an
#: interrupt (µs); the scheduler's slices on a shared core are longer still
SLICE_MS = 0.2


def _spin_on(core: int, ready) -> None:
    os.sched_setaffinity(0, {core})
    ready.set()
    while True:
        pass


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="needs Linux's sched_setaffinity")
def test_a_process_sharing_the_core_makes_gaps_off_its_core():
    """The probe pinned to one core with a busy process pinned there too: the scheduler alternates them, and the
    probe records the other's time slices as gaps its thread's CPU clock did not count."""
    core = min(os.sched_getaffinity(0))
    mine = os.sched_getaffinity(0)
    ctx = multiprocessing.get_context("spawn")
    ready = ctx.Event()
    other = ctx.Process(target=_spin_on, args=(core, ready), daemon=True)
    other.start()
    try:
        assert ready.wait(60.0), "the competing process did not start"
        os.sched_setaffinity(0, {core})
        st = stalls.probe(SHARED_SECONDS, burst_s=SHARED_SECONDS)
    finally:
        os.sched_setaffinity(0, mine)
        other.terminate()
        other.join()
    assert st.seconds == pytest.approx(SHARED_SECONDS)
    assert st.over(SLICE_MS, on_core=False) >= 1, (st.wall_s * 1e3, st.cpu_s * 1e3)
    assert st.longest_ms(on_core=False) > SLICE_MS
    # every recorded gap is over the threshold, and the thread's CPU time across a gap is at most the gap's (the
    # two clocks are read a few microseconds apart)
    assert np.all(st.wall_s > stalls.THRESHOLD_S)
    assert np.all(st.cpu_s <= st.wall_s + timing.OFF_CORE_S)


def test_the_clock_only_solver_returns_at_its_deadline_and_not_before():
    """The deadline section's floor: it reads the clock until its budget has passed (never returns sooner; how much
    later is the machine's, not asserted) and reports the status of a solve that ran to its deadline."""
    budget_s = 2e-3
    stalls.clock_only(budget_s)                 # compiled (or loaded) before it is timed
    start = time.perf_counter()
    assert stalls.clock_only(budget_s) == "budget_exhausted"
    assert time.perf_counter() - start >= budget_s


def test_gaps_are_counted_on_and_off_the_core_and_joined():
    """Synthetic gaps: 0.3 ms off the core (its CPU clock counted 0.01 ms of it), 0.8 ms on it, 2 ms off it."""
    a = stalls.Stalls(1.0, np.array([0.3e-3, 0.8e-3]), np.array([0.01e-3, 0.8e-3]))
    b = stalls.Stalls(3.0, np.array([2e-3]), np.array([0.0]))
    st = stalls.Stalls.joined([a, b])
    assert st.seconds == 4.0
    assert st.off_core.tolist() == [True, False, True]
    assert st.over(0.1) == 3 and st.over(0.5) == 2 and st.over(0.5, on_core=True) == 1
    assert st.over(0.5, on_core=False) == 1
    assert st.longest_ms() == pytest.approx(2.0) and st.longest_ms(on_core=True) == pytest.approx(0.8)
    # a deadline passed by more than 0.5 ms: in the last 0.3 ms of the 0.8 ms gap and the last 1.5 ms of the 2 ms
    # one, 1.8 ms of the 4 s probed
    assert st.share_past(0.5) == pytest.approx(1.8e-3 / 4.0)
    assert st.share_past(0.1) == pytest.approx((0.2 + 0.7 + 1.9) * 1e-3 / 4.0)
    assert stalls.Stalls.joined([]).longest_ms() == 0.0


def test_the_deadline_section_has_a_row_of_stalls_per_load():
    """A load's probe beside its cells: the solves that ran to their deadline (ended at most LATE_MS before it),
    how many of them the stalls make late by more than 0.1 and 0.5 ms (that count times the share of time a stall
    has that much left), and how many were."""
    probe = SimpleNamespace(load="no load added",
                            stalls=stalls.Stalls(10.0, np.array([0.2e-3, 0.7e-3, 1.5e-3]), np.array([0.2e-3, 0, 0])))
    overrun_ms = np.array([-0.2, 0.05, 0.9, -0.02])
    cell = SimpleNamespace(case="3-RPR, legs without an assembly", solver="glpma", load="no load added",
                           budget_ms=2.0, elapsed_s=(overrun_ms + 2.0) / 1e3, overrun_ms=overrun_ms,
                           preempted=np.zeros(4, dtype=bool), collected=np.zeros(4, dtype=bool),
                           off_core=np.zeros(4, dtype=bool), statuses={"budget_exhausted": 4})
    row = stalls_cells(probe, [cell])
    # 3 solves to their deadline; past by > 0.1 ms: (0.1 + 0.6 + 1.4) ms of 10 s; by > 0.5 ms: (0.2 + 1.0) ms
    assert row == ["no load added", "10", 3, 2, "1.5", "0.2", 3, "0.00063 / 1", "0.00036 / 1"], row
    text = "\n".join(deadline_section({"deadline": [cell, probe], "figures": {}}, "BENCHMARKS.md"))
    assert "| " + " | ".join(STALLS_HEAD) + " |" in text and "| no load added | 10 | 3 | 2 |" in text, text


def test_the_hosts_steal_time_reads_as_seconds_that_only_grow():
    """Part 4's host steal column: the machine's steal time in seconds where Linux reports it, never decreasing."""
    first = timing.steal_s()
    if first is None:
        pytest.skip("this system reports no steal time (/proc/stat)")
    assert first >= 0.0 and timing.steal_s() >= first
