"""Measuring on a shared machine, for every tool that times (``glpma-fk bench``, ``glpma-fk stress``,
``tools/bench_gough.py``, ``tools/bench_families.py``): timed calls and the warm-up before them, the machine,
load and revision a measurement names.

Each call is timed with the wall clock and flagged when another process preempted it (the
thread's involuntary context switches grew), when the thread was off its core without a context switch
(the wall clock ran ahead of the thread's CPU clock: an interrupt, or the hypervisor running another
virtual machine) or when Python's garbage collector ran during it: on a shared machine these explain
most overruns, so the reports also give the figures without them."""
from __future__ import annotations

import contextlib
import gc
import multiprocessing
import os
import platform
import subprocess
import time
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
#: the libraries whose versions a report names
LIBRARIES = ("numpy", "numba", "scipy", "pypop7", "pymoo")
#: a call that returns within its budget plus this margin is on time
DEADLINE_MARGIN_MS = 0.5
#: a series stops after this many calls if every one overran by more than STOP_OVERRUN_FACTOR x budget
STOP_AFTER = 10
STOP_OVERRUN_FACTOR = 10.0
#: warm-up: calls in a row on time before timing starts, and the most calls it may take
WARM_UP_QUIET = 20
WARM_UP_MAX_CALLS = 500
#: evaluation cap that never ends a search before its deadline
NO_CAP = 10**9
#: a call whose wall time exceeds its thread's CPU time by more than this (s) was off its core: the timed
#: calls compute and never wait, and the clocks' reads around a call differ by a few microseconds
OFF_CORE_S = 50e-6


def progress_bar(iterable, desc, progress: bool, total=None):
    """``iterable`` with a tqdm progress bar when ``progress``."""
    if not progress:
        return iterable
    from tqdm import tqdm  # the tools extra: optional, imported where used
    return tqdm(iterable, desc=desc, total=total, leave=False, dynamic_ncols=True)


def involuntary_switches() -> int:
    """Involuntary context switches of this thread so far (Linux; 0 elsewhere)."""
    try:
        import resource  # POSIX only: optional, imported where used
        who = getattr(resource, "RUSAGE_THREAD", resource.RUSAGE_SELF)
        return int(resource.getrusage(who).ru_nivcsw)
    except (ImportError, OSError):
        return 0


def steal_s() -> float | None:
    """The time the hypervisor has run something else while this virtual machine's CPUs were runnable ("steal",
    summed over its CPUs, s; Linux's ``/proc/stat``, in clock ticks: 10 ms steps), None where not reported."""
    try:
        with open("/proc/stat") as f:
            fields = f.readline().split()
        return int(fields[8]) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


def infeasible_legs(model) -> np.ndarray:
    """Leg lengths of the shipped configs' geometries with no real assembly (the platform cannot
    reach the base joints), so that a search runs until its deadline or its evaluation cap.  The
    Estimator tells these from the legs alone (a pair of legs too short for its loop)."""
    if model.kind == "planar_3rpr":
        return np.array([10.0, 10.0, 400.0])
    return np.full(model.n_legs, 100.0)


def probed_infeasible_legs(model) -> np.ndarray:
    """Leg lengths of the shipped configs' geometries with no real assembly that every pair of legs
    could close (:mod:`glpma_ros.models.reach`): the Estimator needs its search and its probe to tell."""
    if model.kind == "planar_3rpr":
        return np.array([400.0, 400.0, 400.0])
    return np.tile([900.0, 1600.0], model.n_legs // 2)


def _spin() -> None:
    # normal scheduling whatever the parent's (a real-time parent's children inherit its policy)
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    while True:
        pass


@contextlib.contextmanager
def busy_cores(n: int):
    """``n`` processes that each keep a core busy (a plain Python loop) while the block runs: the load
    generator of the bench's "cores busy" measurements."""
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_spin, daemon=True) for _ in range(n)]
    for p in procs:
        p.start()
    try:
        yield
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.join()


def warm_up(call, budget_ms: float, quiet: int = WARM_UP_QUIET, max_calls: int = WARM_UP_MAX_CALLS) -> int:
    """``call(i)`` until ``quiet`` calls in a row return within ``budget_ms`` + the margin (Numba
    compiles each path on first use, and caches and branch predictors settle), or ``max_calls``
    calls; returns the calls made."""
    in_row = 0
    for i in range(max_calls):
        t0 = time.perf_counter()
        call(i)
        in_row = in_row + 1 if (time.perf_counter() - t0) * 1e3 <= budget_ms + DEADLINE_MARGIN_MS else 0
        if in_row >= quiet:
            return i + 1
    return max_calls


@dataclass
class TimedCalls:
    """Per call: wall time (s), preempted, garbage collector ran, what the call returned, off its core
    (wall time more than :data:`OFF_CORE_S` over the thread's CPU time, without a context switch), and the
    thread's CPU time (s): a call's wall time less it is the time the thread was off its core."""

    budget_ms: float
    elapsed_s: np.ndarray
    preempted: np.ndarray
    collected: np.ndarray
    results: list = field(default_factory=list)
    stopped_early: bool = False
    off_core: np.ndarray | None = None
    cpu_s: np.ndarray | None = None

    @property
    def overrun_ms(self) -> np.ndarray:
        return self.elapsed_s * 1e3 - self.budget_ms

    def on_time_pct(self, undisturbed: bool = False) -> float | None:
        """Share of the calls (or of those neither preempted nor collected) on time, in %."""
        over = self.overrun_ms[~(self.preempted | self.collected)] if undisturbed else self.overrun_ms
        return 100.0 * float(np.mean(over <= DEADLINE_MARGIN_MS)) if over.size else None

    def worst_overrun_ms(self, undisturbed: bool = False) -> float | None:
        over = self.overrun_ms[~(self.preempted | self.collected)] if undisturbed else self.overrun_ms
        return float(over.max()) if over.size else None


def timed_calls(call, n: int, budget_ms: float, desc: str = "", progress: bool = False,
                stop_early: bool = True, rest_s: float = 0.0) -> TimedCalls:
    """``n`` timed calls ``call(i)``; with ``stop_early`` the series stops after :data:`STOP_AFTER`
    calls that all overran by more than :data:`STOP_OVERRUN_FACTOR` times the budget; ``rest_s``: a sleep
    before each call, not timed (a real-time thread that never sleeps is throttled by the kernel)."""
    collections = [0]

    def on_gc(phase, info):
        if phase == "start":
            collections[0] += 1

    el, cpu, pre, col, off, results = [], [], [], [], [], []
    stopped = False
    gc.collect()
    gc.callbacks.append(on_gc)
    try:
        for i in progress_bar(range(n), desc, progress):
            if rest_s:
                time.sleep(rest_s)
            c0, g0 = involuntary_switches(), collections[0]
            cpu0 = time.thread_time()
            t0 = time.perf_counter()
            results.append(call(i))
            el.append(time.perf_counter() - t0)
            cpu.append(time.thread_time() - cpu0)
            off.append(el[-1] - cpu[-1] > OFF_CORE_S)
            pre.append(involuntary_switches() > c0)
            col.append(collections[0] > g0)
            if (stop_early and i + 1 == STOP_AFTER and n > STOP_AFTER
                    and min(el) * 1e3 > (1.0 + STOP_OVERRUN_FACTOR) * budget_ms):
                stopped = True
                break
    finally:
        gc.callbacks.remove(on_gc)
    return TimedCalls(budget_ms, np.array(el), np.array(pre, dtype=bool), np.array(col, dtype=bool), results,
                      stopped, np.array(off, dtype=bool) & ~np.array(pre, dtype=bool), np.array(cpu))


def _version(name):
    try:
        return version(name)
    except PackageNotFoundError:
        return "not installed"


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> dict:
    return {"cpu": cpu_model(), "cores": os.cpu_count(), "os": f"{platform.system()} {platform.release()}",
            "python": platform.python_version(), **{name: _version(name) for name in LIBRARIES}}


def git_revision() -> str:
    def git(*args):
        return subprocess.run(["git", "-C", str(REPO_ROOT), *args], capture_output=True, text=True,
                              timeout=5).stdout.strip()
    try:
        rev, dirty = git("rev-parse", "--short", "HEAD"), git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return rev + (" (with uncommitted changes)" if dirty else "") if rev else "unknown"


@dataclass
class RunConditions:
    """What a stand-alone measurement ran in: the load average (1 min) before and after it, its wall time."""

    load_before: float
    load_after: float
    elapsed_s: float

    def sentence(self, seed: int) -> str:
        """The report's line on the machine and its load (the tools beside the bench: ``tools/bench_*.py``)."""
        cpu = platform.processor() or platform.machine()
        return (f"Measured on {os.cpu_count()} cores ({cpu}), load average (1 min) {self.load_before:.1f} before "
                f"and {self.load_after:.1f} after the run ({self.elapsed_s:.0f} s), shared with other work; "
                f"seed {seed}.")


def measured_run(run):
    """``run()`` and the :class:`RunConditions` it ran in."""
    load_before, t0 = os.getloadavg()[0], time.perf_counter()
    result = run()
    return result, RunConditions(load_before, os.getloadavg()[0], time.perf_counter() - t0)


def emit_report(text: str, markdown: str | None) -> None:
    """Print a tool's Markdown report, and write it to ``markdown`` too when given."""
    print(text)
    if markdown:
        with open(markdown, "w") as f:
            f.write(text)
