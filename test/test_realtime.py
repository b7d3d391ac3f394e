"""The real-time solving thread: ``thread_priority`` (SCHED_FIFO) and ``cpu_affinity``, applied to the
thread that solves; refused (no CAP_SYS_NICE, RLIMIT_RTPRIO 0, a core the process may not use): one
warning line naming why, and the node runs on."""
import errno
import logging
import os
import subprocess
import sys
import textwrap
import threading

import pytest

from conftest import GENEROUS_BUDGET_MS, RPR_YAML
from glpma_ros.errors import InputError
from glpma_ros.node import params as P
from glpma_ros.node import realtime
from glpma_ros.node.loops import SolveLoop
from glpma_ros.node.realtime import RealtimeSettings
from glpma_ros.node.service import FkService

LEGS_M = [0.100, 0.120, 0.150]      # the seed 3-RPR's example legs, in metres


def _in_thread(fn):
    """``fn()`` in a new thread; returns ``(fn's result, the thread's native id)``."""
    out = {}

    def run():
        out["tid"] = threading.get_native_id()
        out["result"] = fn()
    t = threading.Thread(target=run)
    t.start()
    t.join()
    return out["result"], out["tid"]


def _may_use_fifo() -> bool:
    """This process may set SCHED_FIFO (root with CAP_SYS_NICE, or an rtprio limit)."""
    def probe():
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
            return True
        except PermissionError:
            return False
    return _in_thread(probe)[0]


def test_the_parameters_are_declared_with_ranges():
    assert P.SPECS["thread_priority"].default == 0 and P.SPECS["thread_priority"].range == (0, 99)
    assert P.SPECS["cpu_affinity"].default == [] and P.SPECS["cpu_affinity"].type == P.INTEGER_ARRAY
    assert P.coerce("cpu_affinity", [1, 0]) == [1, 0] and P.coerce("thread_priority", 80) == 80
    for name, bad in (("thread_priority", 100), ("thread_priority", -1), ("cpu_affinity", [-1]),
                      ("cpu_affinity", ["0"]), ("cpu_affinity", [0, 0]), ("cpu_affinity", [0.5])):
        with pytest.raises(InputError, match=name):
            P.coerce(name, bad)
    assert not RealtimeSettings.from_params(P.defaults()).active


@pytest.mark.skipif(not _may_use_fifo(), reason="this process may not use SCHED_FIFO (no CAP_SYS_NICE, rtprio 0)")
def test_the_solving_thread_gets_fifo_priority_and_affinity():
    """The success path (root here): the thread that solves runs under SCHED_FIFO at the priority, on the
    cores; another thread of the process is left as it was."""
    core = min(os.sched_getaffinity(0))
    svc = FkService({"manipulator_config": str(RPR_YAML), "thread_priority": 10, "cpu_affinity": [core]})
    loop = SolveLoop(svc, lambda pose: None, stats=svc.stats, modes=svc.modes)
    seen = {}

    def solve():
        loop.offer(LEGS_M, 0)
        tid = threading.get_native_id()
        seen.update(policy=os.sched_getscheduler(tid), priority=os.sched_getparam(tid).sched_priority,
                    cores=os.sched_getaffinity(tid))
    _in_thread(solve)
    assert seen == {"policy": os.SCHED_FIFO, "priority": 10, "cores": {core}}
    assert loop.realtime.applied == 1 and not loop.realtime.problems
    assert os.sched_getscheduler(0) == os.SCHED_OTHER          # this (main) thread untouched


def test_the_extras_thread_runs_one_priority_below_on_any_core():
    """The extras thread takes the interpreter lock between two solves: real-time one below the solving
    thread (so that no normal process preempts it while the solving thread waits for the lock), at least 1,
    on the process's cores; nothing when the solving thread is not real-time."""
    assert RealtimeSettings(50, (1,)).helper() == RealtimeSettings(49, ())
    assert RealtimeSettings(1).helper() == RealtimeSettings(1)
    assert not RealtimeSettings(0, (1,)).helper().active
    svc = FkService({"manipulator_config": str(RPR_YAML), "thread_priority": 10})
    loop = SolveLoop(svc, lambda pose: None, publish_extras=lambda ex: None, stats=svc.stats, modes=svc.modes)
    assert loop.extras.realtime.settings == RealtimeSettings(9)
    assert loop.extras.realtime.log is None     # a refusal is the solving thread's one warning line


@pytest.mark.skipif(not _may_use_fifo(), reason="this process may not use SCHED_FIFO (no CAP_SYS_NICE, rtprio 0)")
def test_the_extras_thread_gets_its_priority():
    svc = FkService({"manipulator_config": str(RPR_YAML), "thread_priority": 10, "publish_tf": True,
                     "time_budget_ms": GENEROUS_BUDGET_MS})   # a pose whatever the load: its extras are published
    seen = {}

    def publish_extras(ex):
        tid = threading.get_native_id()
        seen.update(policy=os.sched_getscheduler(tid), priority=os.sched_getparam(tid).sched_priority)
    loop = SolveLoop(svc, lambda pose: None, publish_extras=publish_extras, stats=svc.stats, modes=svc.modes)
    try:
        _in_thread(lambda: loop.offer(LEGS_M, 0))
        assert loop.extras.flush(timeout=120.0)      # a bound for a hang: the first extras may load compiled code
    finally:
        loop.stop()
    assert seen == {"policy": os.SCHED_FIFO, "priority": 9}
    assert loop.extras.realtime.applied == 1


def test_a_refused_priority_is_one_warning_and_the_node_runs_on(monkeypatch, caplog):
    """The refusal injected (EPERM from the kernel): one warning line naming why, for any number of solving
    threads; the inputs are solved."""
    def refuse(*args):
        raise PermissionError(errno.EPERM, "Operation not permitted")
    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    monkeypatch.setattr(realtime, "rtprio_limit", lambda: (0, 0))
    # the node's logger handed in: what it is told, whatever logging configuration the process has (a sourced
    # ROS 2 loads launch's pytest plugins, which reconfigure the logging module)
    logger = logging.getLogger("test_realtime.refused")
    logger.propagate = False
    logger.addHandler(caplog.handler)
    try:
        svc = FkService({"manipulator_config": str(RPR_YAML), "thread_priority": 50,
                         "time_budget_ms": GENEROUS_BUDGET_MS}, logger=logger)
        published = []
        loop = SolveLoop(svc, published.append, stats=svc.stats, modes=svc.modes)
        with caplog.at_level(logging.WARNING, logger=logger.name):
            for _ in range(3):
                _in_thread(lambda: loop.offer(LEGS_M, 0))
    finally:
        logger.removeHandler(caplog.handler)
    warnings = [r.getMessage() for r in caplog.records if "thread_priority" in r.getMessage()]
    assert len(warnings) == 1 and "\n" not in warnings[0], warnings
    assert "CAP_SYS_NICE" in warnings[0] and "RLIMIT_RTPRIO of at least 50" in warnings[0] and "soft 0" in warnings[0]
    assert len(published) == 3                 # solved in every thread all the same


def test_a_core_the_process_may_not_use_is_named():
    problems = realtime.apply(RealtimeSettings(0, (4000,)))
    assert len(problems) == 1 and "cpu_affinity [4000]" in problems[0] and "not available" in problems[0]


def test_the_kernel_refuses_fifo_without_privilege_or_rtprio():
    """The refusal for real: a child process lowers its RLIMIT_RTPRIO to 0 and, as root, drops to an
    unprivileged user (root's CAP_SYS_NICE would otherwise allow it), then asks for SCHED_FIFO."""
    code = textwrap.dedent("""
        import os, resource
        from glpma_ros.node.realtime import RealtimeSettings, apply    # imported while files can be read
        resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))
        if os.geteuid() == 0:
            os.setgid(65534); os.setuid(65534)
        print(apply(RealtimeSettings(20, ()))[0])
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    line = out.stdout.strip()
    assert line.startswith("thread_priority 20 not applied") and "soft 0, hard 0" in line, line
    assert "\n" not in line
