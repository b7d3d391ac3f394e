"""How long an input waits for anything but its own solve, in-process.

An input's wall time in the solving thread is its own work (CPU time of that thread,
``time.thread_time_ns``) plus the time the thread was not running: *blocked* -- waiting for a
lock or for the interpreter (the GIL) held by another thread (a report, the extras thread) -- or
*runnable* but waiting for a CPU the machine gave to another process (the kernel's run delay,
``/proc/self/task/<tid>/schedstat``).  This section measures, per input,
``blocked = wall - thread CPU - run delay``, the wait for anything but its own solve that the
node causes itself, and the wall time, in three setups
with the same warm 3-RPR inputs:

* ``handle`` -- :meth:`FkService.handle` alone, back to back: the machine's noise, the baseline;
* ``handle + reports`` -- the same with a thread making a report as the node's
  :class:`~glpma_ros.node.loops.ReportLoop` does, every :data:`REPORT_PERIOD_S` (200 times the node's default rate, so that a round meets hundreds of
  reports);
* ``node at 1 kHz`` -- the node's path as it runs: inputs every :data:`NODE_PERIOD_S` through
  :meth:`SolveLoop.offer`, the pose's extra outputs (TF, covariance, twist) built by the extras
  thread, and a :class:`~glpma_ros.node.loops.ReportLoop` at the default ``diagnostics_period_s``.

Rounds alternate between the setups (``rounds`` each); the quietest round of each setup is
reported (the one with the fewest inputs over :data:`SLOW_S`), as the machine's load varies
between rounds.  Issue 24 measured the first two before the reports were taken off the
service's lock: inputs over 0.3 ms from 0 to 16, ``handle()`` p99.9 from 55 to 532 us.
"""
from __future__ import annotations

import os
import threading
import time

import numpy as np

from glpma_ros.config import config_dir
from glpma_ros.node import params as P
from glpma_ros.node.loops import ReportLoop, SolveLoop, pause_report
from glpma_ros.node.service import FkService
from glpma_tools.sim.trajectories import variables_along

#: period of the reporting thread (s): 200x the node's default diagnostics rate
REPORT_PERIOD_S = 0.005
#: the input period of the node's path (s): 1 kHz, the rate the node is built for
NODE_PERIOD_S = 1e-3
#: an input slower than this (s) counts as slow: a third of a 1 kHz period
SLOW_S = 0.3e-3
#: the tail quantile reported (99.9 %: one input in a thousand, one a second at 1 kHz)
TAIL = 99.9
#: the goal for the tail of the wait (us)
WAIT_GOAL_US = 20.0
SETUPS = ("handle", "handle + reports", "node at 1 kHz")
#: parameters of the measured node: the shipped 3-RPR, with the extra outputs of the last setup
PARAMS = {"manipulator_config": str(config_dir() / "planar_3rpr_seed.yaml")}
EXTRAS = {"publish_tf": True, "publish_covariance": True, "publish_twist": True}


class _Reporter:
    """A thread calling ``service.diagnostics()`` every ``period_s`` until stopped."""

    def __init__(self, service, period_s: float):
        self.service, self.period_s = service, period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

        self.cpu_s: list = []       # thread CPU time of each report: the longest it can hold the interpreter

    def _run(self):
        while not self._stop.wait(self.period_s):
            c0 = time.thread_time()
            self.service.diagnostics(pause=pause_report)
            self.cpu_s.append(time.thread_time() - c0)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def _inputs(service, n: int) -> list:
    """``n`` leg-length inputs (metres) along the simulated loop, each a small step from the last."""
    model = service.model
    xs = variables_along(model, model.variables_from_pose([0.25 * model.scale, 0.25 * model.scale, model.scale],
                                                          [0.0, 0.0, 0.0, 1.0]), n)
    return [tuple(model.inverse_kinematics(x) * service.metres_per_unit) for x in xs]


class _RunDelay:
    """Nanoseconds the calling thread has spent runnable but not running (waiting for a CPU: the
    machine's load), from ``/proc/self/task/<tid>/schedstat``; 0 where the kernel does not say."""

    def __init__(self):
        try:
            self._fd = os.open(f"/proc/self/task/{threading.get_native_id()}/schedstat", os.O_RDONLY)
        except OSError:
            self._fd = None

    def __call__(self) -> int:
        return 0 if self._fd is None else int(os.pread(self._fd, 128, 0).split()[1])

    def close(self):
        if self._fd is not None:
            os.close(self._fd)


def _round(call, inputs, period_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wall time, thread CPU time and run delay (s) of ``call(legs, stamp_ns)`` per input, the
    inputs ``period_s`` apart (0: back to back)."""
    wall, cpu, delay = (np.empty(len(inputs)) for _ in range(3))
    run_delay = _RunDelay()
    start = time.perf_counter()
    try:
        for k, legs in enumerate(inputs):
            if period_s:
                time.sleep(max(0.0, start + k * period_s - time.perf_counter()))
            d0 = run_delay()
            t0, c0 = time.perf_counter_ns(), time.thread_time_ns()
            call(legs, k + 1)
            c1, t1 = time.thread_time_ns(), time.perf_counter_ns()
            wall[k], cpu[k], delay[k] = (t1 - t0) * 1e-9, (c1 - c0) * 1e-9, (run_delay() - d0) * 1e-9
    finally:
        run_delay.close()
    return wall, cpu, delay


def _row(setup, wall, cpu, delay, report_cpu, reports) -> dict:
    # the clocks differ by their resolutions: a negative difference is none
    off_cpu = np.maximum(wall - cpu, 0.0)
    blocked = np.maximum(off_cpu - delay, 0.0)
    return {"setup": setup, "inputs": int(wall.size), "reports": reports,
            "report cpu p50 us": float(np.percentile(report_cpu, 50) * 1e6) if report_cpu else None,
            "report cpu max us": float(np.max(report_cpu) * 1e6) if report_cpu else None,
            "slow": int(np.sum(wall > SLOW_S)),
            "wall p50 us": _us(wall, 50), "wall p99.9 us": _us(wall, TAIL),
            "off-cpu p99.9 us": _us(off_cpu, TAIL),
            "blocked p50 us": _us(blocked, 50), "blocked p99.9 us": _us(blocked, TAIL),
            "blocked max us": float(blocked.max() * 1e6)}


def _us(values, q) -> float:
    return float(np.percentile(values, q) * 1e6)


def measure(rounds: int = 4, inputs: int = 5000, period_s: float = REPORT_PERIOD_S) -> list[dict]:
    """The quietest of ``rounds`` rounds of ``inputs`` inputs per setup (:data:`SETUPS`)."""
    service = FkService(PARAMS)
    service.warm_up()
    legs = _inputs(service, inputs)
    node = FkService({**PARAMS, **EXTRAS})
    node.warm_up()
    loop = SolveLoop(node, lambda pose: None, publish_extras=lambda extras: None)
    best: dict = {}
    try:
        for _ in range(rounds):
            for setup in SETUPS:
                if setup == "handle":
                    wall, cpu, delay = _round(service.handle, legs)
                    report_cpu = []
                elif setup == "handle + reports":
                    with _Reporter(service, period_s) as reporter:
                        wall, cpu, delay = _round(service.handle, legs)
                    report_cpu = reporter.cpu_s
                else:
                    made: list = []
                    reporter = ReportLoop(node, made.append, P.SPECS["diagnostics_period_s"].default).start()
                    try:
                        wall, cpu, delay = _round(loop.offer, legs, NODE_PERIOD_S)
                    finally:
                        reporter.stop()
                    loop.extras.flush(10.0)
                    report_cpu = []
                row = _row(setup, wall, cpu, delay, report_cpu, len(made) if setup == "node at 1 kHz" else
                           len(report_cpu))
                if setup not in best or row["slow"] < best[setup]["slow"]:
                    best[setup] = row
    finally:
        loop.stop()
    return [best[s] for s in SETUPS]


def section(res) -> list[str]:
    """The BENCHMARKS.md section (``res["waits"]``: :func:`measure`'s rows), prose from templates/waits.md."""
    from glpma_tools.tables import fmt, table
    from .report import prose
    rows = res.get("waits")
    if not rows:
        return []
    by = {r["setup"]: r for r in rows}
    node = by["node at 1 kHz"]
    return ["## Waits of an input for anything but its own solve", "",
            prose("waits", period_ms=f"{REPORT_PERIOD_S * 1e3:g}", slow_ms=f"{SLOW_S * 1e3:g}"), "",
            table(["setup", "inputs", "reports", f"over {SLOW_S * 1e3:g} ms", "wall p50 us", "wall p99.9 us",
                   "off-CPU p99.9 us", "blocked p50 us", "blocked p99.9 us", "blocked max us"],
                  [[r["setup"], str(r["inputs"]), str(r["reports"]), str(r["slow"]), fmt(r["wall p50 us"]),
                    fmt(r["wall p99.9 us"]), fmt(r["off-cpu p99.9 us"]), fmt(r["blocked p50 us"]),
                    fmt(r["blocked p99.9 us"]), fmt(r["blocked max us"])] for r in rows]), "",
            prose("waits", "reading", blocked=fmt(node["blocked p99.9 us"]), goal=f"{WAIT_GOAL_US:g}",
                  met="met" if node["blocked p99.9 us"] <= WAIT_GOAL_US else "missed"), ""]


if __name__ == "__main__":       # python -m glpma_tools.bench.waits: the table alone
    import json
    print(f"load average {os.getloadavg()}")
    for r in measure():
        print(json.dumps(r))
