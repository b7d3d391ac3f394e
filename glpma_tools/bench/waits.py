"""The ``waits`` section: how long an input waits in-process for anything but its own solve (*blocked* =
wall - thread CPU - the kernel's run delay), in each of three setups (what they run and why:
``templates/waits.md``), the quietest of alternating rounds reported; and :func:`timed`, which times calls."""
from __future__ import annotations

import os
import threading
import time

import numpy as np

from glpma_ros.config import config_dir
from glpma_ros.node import params as P
from glpma_ros.node.loops import ReportLoop, SolveLoop
from glpma_ros.node.service import FkService
from glpma_tools.tables import fmt, table

from .markdown import md_blocks, prose
from .scenarios import load
from .transport import SHIPPED_ON

#: period of the reporting thread of ``handle + reports`` (s): 200x the node's default diagnostics rate,
#: so that a round meets hundreds of reports
REPORT_PERIOD_S = 0.005
#: the input period of the node's path (s): 1 kHz, the rate the node is built for
NODE_PERIOD_S = 1e-3
#: an input slower than this (s) counts as slow: a third of a 1 kHz period
SLOW_S = 0.3e-3
#: the tail quantile reported (99.9 %: one input in a thousand, one a second at 1 kHz)
TAIL = 99.9
#: the goal for the tail of the wait (us)
WAIT_GOAL_US = 20.0
#: parameters of the measured node: the shipped 3-RPR, with the extra outputs of the last setup
PARAMS = {"manipulator_config": str(config_dir() / "planar_3rpr_seed.yaml")}
#: seconds to wait for the extras thread to finish a round's poses
FLUSH_S = 10.0
#: the columns of a row (us): the series and its percentile (100: the largest)
COLUMNS = {"wall p50 us": ("wall", 50), "wall p99.9 us": ("wall", TAIL), "off-cpu p99.9 us": ("off-cpu", TAIL),
           "blocked p50 us": ("blocked", 50), "blocked p99.9 us": ("blocked", TAIL),
           "blocked max us": ("blocked", 100)}


def timed(call, inputs, period_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wall time, thread CPU time and run delay (s) of ``call(*item)`` per item of ``inputs``, the calls
    ``period_s`` apart (0: back to back)."""
    wall, cpu, delay = (np.empty(len(inputs)) for _ in range(3))
    schedstat = f"/proc/self/task/{threading.get_native_id()}/schedstat"
    fd = os.open(schedstat, os.O_RDONLY) if os.path.exists(schedstat) else None

    def run_delay() -> int:     # the second field of the thread's schedstat; 0 where the kernel does not say
        return 0 if fd is None else int(os.pread(fd, 128, 0).split()[1])

    start = time.perf_counter()
    try:
        for k, item in enumerate(inputs):
            if period_s:
                time.sleep(max(0.0, start + k * period_s - time.perf_counter()))
            d0 = run_delay()
            t0, c0 = time.perf_counter_ns(), time.thread_time_ns()
            call(*item)
            c1, t1 = time.thread_time_ns(), time.perf_counter_ns()
            wall[k], cpu[k], delay[k] = (t1 - t0) * 1e-9, (c1 - c0) * 1e-9, (run_delay() - d0) * 1e-9
    finally:
        if fd is not None:
            os.close(fd)
    return wall, cpu, delay


def _row(setup, wall, cpu, delay, reports) -> dict:
    off_cpu = np.maximum(wall - cpu, 0.0)       # the clocks differ by their resolutions: a negative difference is none
    series = {"wall": wall, "off-cpu": off_cpu, "blocked": np.maximum(off_cpu - delay, 0.0)}
    return {"setup": setup, "inputs": int(wall.size), "reports": reports, "slow": int(np.sum(wall > SLOW_S)),
            **{key: float(np.percentile(series[name], q) * 1e6) for key, (name, q) in COLUMNS.items()}}


def measure(rounds: int = 4, inputs: int = 5000, period_s: float = REPORT_PERIOD_S) -> list[dict]:
    """The quietest of ``rounds`` rounds of ``inputs`` inputs per setup, a row each."""
    service = FkService(PARAMS)
    service.warm_up()
    legs = [(tuple(legs), k + 1) for k, legs in enumerate(load("3rpr").along(inputs)[1] * service.metres_per_unit)]
    node = FkService({**PARAMS, **SHIPPED_ON})
    node.warm_up()
    loop = SolveLoop(node, lambda pose: None, publish_extras=lambda extras: None, stats=node.stats, modes=node.modes)
    # setup -> (the service reported on, report period (None: no reports), the call, the input period)
    setups = {"handle": (service, None, service.handle, 0.0),
              "handle + reports": (service, period_s, service.handle, 0.0),
              "node at 1 kHz": (node, P.SPECS["diagnostics_period_s"].default, loop.offer, NODE_PERIOD_S)}
    best: dict = {}
    try:
        for _ in range(rounds):
            for setup, (svc, report_period, call, input_period) in setups.items():
                made: list = []
                reporter = ReportLoop(svc.reporter, made.append, report_period, log=svc.log).start() \
                    if report_period else None
                try:
                    wall, cpu, delay = timed(call, legs, input_period)
                finally:
                    if reporter:
                        reporter.stop()
                loop.extras.flush(FLUSH_S)
                row = _row(setup, wall, cpu, delay, len(made))
                best[setup] = min(best.get(setup, row), row, key=lambda r: r["slow"])     # the first of the quietest
    finally:
        loop.stop()
    return list(best.values())


def section(res, md_path=None) -> list[str]:
    """The BENCHMARKS.md section (``res["waits"]``: :func:`measure`'s rows), prose from templates/waits.md."""
    rows = res["waits"]
    blocked = {r["setup"]: r for r in rows}["node at 1 kHz"]["blocked p99.9 us"]
    return md_blocks("## Waits of an input for anything but its own solve",
                     prose("waits", period_ms=f"{REPORT_PERIOD_S * 1e3:g}", slow_ms=f"{SLOW_S * 1e3:g}"),
                     table(["setup", "inputs", "reports", f"over {SLOW_S * 1e3:g} ms",
                            *(k.replace("off-cpu", "off-CPU") for k in COLUMNS)],
                           [[r["setup"], r["inputs"], r["reports"], r["slow"], *(fmt(r[k]) for k in COLUMNS)]
                            for r in rows]),
                     prose("waits", "reading", blocked=fmt(blocked), goal=f"{WAIT_GOAL_US:g}",
                           met="met" if blocked <= WAIT_GOAL_US else "missed"))
