"""A real-time solving thread, as ros2_control's controller manager offers one: the thread that
solves the inputs runs under ``SCHED_FIFO`` at ``thread_priority`` and/or on the cores of
``cpu_affinity`` (parameters of both transports).

The settings go to each thread the first time it solves (the rclpy executor's thread, the DDS
transport's reader threads, or the solve loop's own thread), by its native id
(``os.sched_setscheduler`` / ``os.sched_setaffinity`` act on one thread when given a thread id on
Linux).  A ``SCHED_FIFO`` thread runs before every normal (``SCHED_OTHER``) thread of the machine
until it blocks: a busy machine then delays a solve by the interrupts and the other real-time
threads only, not by the other processes.

Linux lets a process use ``SCHED_FIFO`` up to its ``RLIMIT_RTPRIO`` (``ulimit -r``; limits.conf's
``rtprio``), or at any priority with ``CAP_SYS_NICE``.  When it may not, the node says why in one
warning line and runs on at normal priority.  No ROS import.
"""
from __future__ import annotations

import errno
import os
import resource
import threading
from dataclasses import dataclass

#: the highest SCHED_FIFO priority Linux accepts (the parameter's range)
MAX_PRIORITY = 99


def _cores(cores) -> str:
    return "[" + ", ".join(str(c) for c in sorted(cores)) + "]"


def rtprio_limit() -> tuple[int, int]:
    """This process's ``RLIMIT_RTPRIO`` (soft, hard): the highest SCHED_FIFO priority it may set
    without ``CAP_SYS_NICE``."""
    soft, hard = resource.getrlimit(resource.RLIMIT_RTPRIO)
    return int(soft), int(hard)


@dataclass(frozen=True)
class RealtimeSettings:
    """``priority``: SCHED_FIFO priority of the solving thread (0: not real-time, the default);
    ``cpus``: the cores it may run on (empty: unchanged)."""

    priority: int = 0
    cpus: tuple = ()

    @classmethod
    def from_params(cls, params: dict) -> "RealtimeSettings":
        return cls(int(params.get("thread_priority", 0)), tuple(int(c) for c in params.get("cpu_affinity", ())))

    @property
    def active(self) -> bool:
        return self.priority > 0 or bool(self.cpus)

    def helper(self) -> "RealtimeSettings":
        """The settings of a thread that shares the interpreter lock with the solving thread (the extras
        thread): ``SCHED_FIFO`` one below it (at least 1), on any core.  At normal priority such a
        thread, preempted by another process while it holds the lock, would keep the real-time
        thread waiting for the lock until the scheduler gives it its core back (a priority inversion)."""
        return RealtimeSettings(max(self.priority - 1, 1) if self.priority > 0 else 0)


def apply(settings: RealtimeSettings, tid: int | None = None) -> list[str]:
    """Apply ``settings`` to the thread ``tid`` (native id; default the calling thread).  Returns one
    line per setting that could not be applied, naming why (nothing is raised)."""
    tid = threading.get_native_id() if tid is None else tid
    problems = []
    if settings.cpus:
        allowed = os.sched_getaffinity(0)
        missing = set(settings.cpus) - allowed
        if missing:
            problems.append(f"cpu_affinity {_cores(settings.cpus)} not applied: core(s) {_cores(missing)} not "
                            f"available to this process (it may use {_cores(allowed)})")
        else:
            try:
                os.sched_setaffinity(tid, settings.cpus)
            except OSError as exc:
                problems.append(f"cpu_affinity {_cores(settings.cpus)} not applied: {exc.strerror}")
    if settings.priority > 0:
        try:
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(settings.priority))
        except OSError as exc:
            problems.append(refusal(settings.priority, exc))
    return problems


def refusal(priority: int, exc: OSError) -> str:
    """The warning line for a SCHED_FIFO ``priority`` the kernel refused with ``exc``."""
    if exc.errno == errno.EPERM:
        soft, hard = rtprio_limit()
        return (f"thread_priority {priority} not applied: SCHED_FIFO needs CAP_SYS_NICE or an RLIMIT_RTPRIO of "
                f"at least {priority} (this process: soft {soft}, hard {hard}); the solving thread runs at normal "
                f"priority (README, 'Real-time thread', says how to grant it)")
    return f"thread_priority {priority} not applied: {exc.strerror or exc}; the solving thread runs at normal priority"


class RealtimeThreads:
    """Applies the settings to every thread that solves, once per thread (the first time it
    solves: :meth:`enter`, a set look-up afterwards); the first refusal is logged as one warning
    line, later ones (another reader thread refused the same way) are not."""

    def __init__(self, settings: RealtimeSettings, log=None):
        self.settings = settings
        self.log = log
        self._done: set = set()
        self._lock = threading.Lock()
        self.problems: list[str] = []       # what could not be applied (the first thread's)
        self.applied = 0                    # threads the settings were applied to without a problem

    def enter(self) -> None:
        """Called by a thread about to solve."""
        if not self.settings.active:
            return
        tid = threading.get_native_id()
        if tid in self._done:
            return
        with self._lock:
            if tid in self._done:
                return
            self._done.add(tid)
            problems = apply(self.settings, tid)
            if not problems:
                self.applied += 1
            elif not self.problems:
                self.problems = problems
                if self.log is not None:
                    self.log.warning("; ".join(problems))
