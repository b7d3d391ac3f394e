"""The threads both transports share: :class:`SolveLoop` solves the newest pending input (an
input replaced before it was picked up counts as dropped) and publishes its pose;
:class:`ExtrasLoop` builds and publishes the pose's TF, covariance, twist and markers after it,
off the real-time path; :class:`AssemblyModesLoop` answers ``~/request_assembly_modes``;
:class:`ReportLoop` publishes ``/diagnostics`` from a thread of its own.  Each is handed the
collaborators it reads -- the :class:`~glpma_ros.node.service.FkService` that solves and builds
the extra outputs, its statistics (``service.stats``), its assembly modes (``service.modes``), its
diagnostics reporter (``service.reporter``) -- wired alike for both transports by :func:`node_loops`."""
from __future__ import annotations

import queue
import threading
import time
from collections import deque

from ..errors import InputError
from .assembly_modes import AssemblyModes
from .diagnostics import Diagnostics
from .realtime import RealtimeSettings, RealtimeThreads
from .service import FkService
from .stats import Statistics


class LatestInput:
    """A one-slot mailbox: a new input replaces the pending one (which is then dropped)."""

    def __init__(self):
        self._cond = threading.Condition()
        self._item = None
        self._closed = False

    def put(self, item) -> bool:
        """Store ``item``; True when it replaced an input nobody had taken yet."""
        with self._cond:
            replaced = self._item is not None
            self._item = item
            self._cond.notify()
            return replaced

    def get(self, timeout: float | None = None):
        """The pending input, waiting up to ``timeout``; ``None`` on timeout or when closed."""
        with self._cond:
            if self._item is None and not self._closed:
                self._cond.wait(timeout)
            item, self._item = self._item, None
            return item

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()


#: poses whose extra outputs may wait for the extras thread (0.1 s at 1 kHz); beyond, the
#: oldest waiting are dropped (counted) -- the pose itself never waits for them
EXTRAS_BACKLOG = 100
#: while poses keep coming, the extras thread looks for new ones every EXTRAS_POLL_S rather than
#: being woken: waking a blocked thread costs the waking (solving) thread a futex call and an
#: inter-processor interrupt (its cost: BENCHMARKS.md, "Extra outputs and the transport path")
EXTRAS_POLL_S = 0.5e-3
#: ... and goes back to a blocking wait (woken by the next hand-off) after this long without one
EXTRAS_LINGER_S = 0.05
#: seconds between two looks of :meth:`ExtrasLoop.flush`
FLUSH_POLL_S = 1e-3


class ExtrasLoop:
    """The extra outputs of each published pose -- TF, covariance, twist, markers -- built
    (:meth:`FkService.extras <glpma_ros.node.service.FkService.extras>`) and published by a thread
    of their own, in the order of the poses, so that the solving thread only hands the outcome
    over and is free for the next input.  An output nobody subscribes to is neither built nor
    written (``subscribed()`` names the outputs that have subscribers; None: all of them).

    Hand-off: the solving thread appends to a queue and wakes the extras thread only when it
    sleeps in a blocking wait; while poses stream in, the extras thread polls the queue every
    :data:`EXTRAS_POLL_S` instead (hybrid polling), so the real-time path pays an append, and an
    extra output follows its pose by at most that period plus its building and writing.

    ``own_thread=False``: no thread; the solving thread builds and writes them itself, right after
    the pose (a transport whose writes release the interpreter lock, where a second Python thread
    would take that lock from the thread taking the next input: the rclpy adapter)."""

    def __init__(self, service: FkService, publish_extras, subscribed=None, name: str = "glpma_fk-extras", *,
                 stats: Statistics, realtime: RealtimeThreads | None = None, own_thread: bool = True):
        """``service`` builds the extra outputs; ``stats``: where their times and drops are counted;
        ``realtime``: applied to the thread when it starts (the solving thread's
        :meth:`~glpma_ros.node.realtime.RealtimeSettings.helper` settings); ``own_thread``: see the class."""
        self.service = service
        self.own_thread = own_thread
        self.realtime = realtime
        self.stats = stats
        self.publish_extras = publish_extras
        self.subscribed = subscribed
        self._pending: deque = deque()       # (outcome, params at hand-off)
        self._bell: queue.SimpleQueue = queue.SimpleQueue()    # wakes the thread from its blocking wait
        self._asleep = False                 # the thread is (about to be) in its blocking wait
        self._handed = self._finished = 0    # poses handed over / published or dropped
        self._closed = False
        self._start_lock = threading.Lock()
        self._thread = None
        self._name = name

    def put(self, outcome) -> None:
        """Hand ``outcome`` (a published pose) over; the thread starts on the first call.  Without a thread of
        its own: publish its extra outputs now."""
        if not self.own_thread:
            if not self._closed:
                self._handed += 1
                self.publish(outcome, self.service.params)
                self._finished += 1
            return
        if self._thread is None:
            with self._start_lock:
                if self._thread is None and not self._closed:
                    self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
                    self._thread.start()
        if self._closed:
            return
        self._handed += 1               # one solving thread at a time (SolveLoop)
        self._pending.append((outcome, self.service.params))
        if self._asleep:                # read after the append: see _run
            self._bell.put(True)

    def _run(self) -> None:
        if self.realtime is not None:
            self.realtime.enter()
        pending, last = self._pending, time.monotonic()
        while True:
            if pending:
                item = pending.popleft()
                if len(pending) >= EXTRAS_BACKLOG:      # behind: the newer ones are kept
                    self.stats.record_extras_dropped(1)
                else:
                    self.publish(*item)
                self._finished += 1
                last = time.monotonic()
            elif self._closed:
                return
            elif time.monotonic() - last < EXTRAS_LINGER_S:
                time.sleep(EXTRAS_POLL_S)
            else:
                # set before the last look: a hand-off after that look sees it and rings
                self._asleep = True
                if not pending and not self._closed:
                    self._bell.get()
                self._asleep = False
                last = time.monotonic()

    def publish(self, outcome, params) -> None:
        """Build and publish the extra outputs of one pose in this thread."""
        t0 = time.perf_counter()
        try:
            subscribed = self.subscribed() if self.subscribed is not None else None
            extras = self.service.extras(outcome, params, subscribed)
            if extras is not None:
                self.publish_extras(extras)
        except Exception as exc:  # noqa: BLE001 - a failed publish must not stop the loop
            self.service.log.error(f"publishing tf / covariance / twist / markers failed: {exc!r}")
        self.stats.record_extras_time(time.perf_counter() - t0)

    def flush(self, timeout: float = 2.0) -> bool:
        """Wait until every pose handed over so far has had its extra outputs published (or
        dropped); False on timeout."""
        end = time.monotonic() + timeout
        while self._finished < self._handed:
            if time.monotonic() > end:
                return False
            time.sleep(FLUSH_POLL_S)
        return True

    def stop(self, timeout: float = 2.0) -> None:
        """Publish what is waiting, then end the thread."""
        with self._start_lock:
            self._closed = True
        if self._thread is not None and self._thread.is_alive():
            self._bell.put(True)
            self._thread.join(timeout)


class SolveLoop:
    """Solves the newest input and publishes its pose (then hands it to an :class:`ExtrasLoop`
    for its extra outputs), one input at a time.  Two ways in:

    * :meth:`offer` (the DDS transport's reader threads): solve in the calling thread at once
      unless a solve is in progress -- then the input waits in a one-slot mailbox, replacing
      (and dropping) any input already waiting, and the thread that is solving takes it next;
      no thread hand-off on the way from input to pose;
    * :meth:`submit`: the input goes to the mailbox and the loop's own thread (started by
      :meth:`start`) solves it -- a thread hand-off per input, which both transports avoid (the
      rclpy adapter solves in the thread that takes its input through :meth:`offer`); BENCHMARKS.md
      compares the two.

    Either way the newest input wins and every input replaced unsolved counts as dropped."""

    def __init__(self, service: FkService, publish, name: str = "glpma_fk-solver", publish_extras=None,
                 subscribed=None, *, stats: Statistics, modes: AssemblyModes, extras_thread: bool = True):
        """``service`` solves each input; ``publish(PoseOutput)``; ``publish_extras(ExtraOutputs)`` (TF,
        covariance, twist, markers; None: not published), called by the extras thread (``extras_thread``,
        else by the solving thread after the pose: :class:`ExtrasLoop`'s ``own_thread``); ``subscribed()``:
        the outputs that have subscribers (see :class:`ExtrasLoop`); ``stats``: where dropped inputs and
        hand-off times are counted; ``modes``: told of every input received (the assembly modes are
        computed for the last one)."""
        self.service = service
        self.publish = publish
        self.stats = stats
        self.modes = modes
        # thread_priority / cpu_affinity: applied to each thread the first time it solves; the extras
        # thread, which takes the interpreter lock between two solves, runs one priority below
        settings = RealtimeSettings.from_params(service.params)
        self.realtime = RealtimeThreads(settings, service.log)
        self.extras = None if publish_extras is None else ExtrasLoop(
            service, publish_extras, subscribed, stats=stats, realtime=RealtimeThreads(settings.helper()),
            own_thread=extras_thread)
        self._cond = threading.Condition()
        self._pending = None            # the input waiting for the solver
        self._busy = False              # a thread is solving (and will take _pending next)
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> "SolveLoop":
        """Start the loop's own thread (needed for :meth:`submit`, not for :meth:`offer`)."""
        self._thread.start()
        return self

    def _item(self, legs_m, stamp_ns: int, arrival: float | None):
        self.modes.note_input(legs_m, stamp_ns)
        return legs_m, int(stamp_ns), time.perf_counter() if arrival is None else arrival

    def submit(self, legs_m, stamp_ns: int) -> None:
        """Hand an input (leg lengths in metres, ``stamp_ns`` = arrival time, or a
        :class:`~glpma_ros.node.service.JointStateInput`, ``stamp_ns`` = its header.stamp) to the loop's thread."""
        self._wait_or_replace(self._item(legs_m, stamp_ns, None))

    def offer(self, legs_m, stamp_ns: int, arrival: float | None = None) -> bool:
        """Solve an input (leg lengths in metres or a :class:`~glpma_ros.node.service.JointStateInput`) in this thread
        unless another is being solved; then it waits for that solve to end (replacing and
        dropping an input already waiting).  Returns True when this thread solved it (and
        whatever arrived meanwhile)."""
        item = self._item(legs_m, stamp_ns, arrival)
        with self._cond:
            if self._busy or self._pending is not None or self._closed:
                replaced = self._pending is not None
                self._pending = item
                self._cond.notify()
            else:
                self._busy = True
                replaced = None
        if replaced is not None:
            if replaced:
                self.stats.record_dropped(1)
            return False
        self._drain(item)
        return True

    def offer_message(self, data, stamp_ns: int, arrival: float | None = None) -> bool:
        """:meth:`offer` for a ``leg_lengths`` message's bytes, solved and its pose published in one compiled call
        (:meth:`FkService.solve_message <glpma_ros.node.service.FkService.solve_message>`) in this thread when
        no other solve is in progress.  False when that does not apply (a solve in progress, or not the one-call
        way's input: nothing done): the caller decodes the message and offers its legs."""
        with self._cond:
            if self._busy or self._pending is not None or self._closed:
                return False
            self._busy = True
        self.realtime.enter()
        try:
            outcome = self.service.solve_message(data, stamp_ns, arrival)
        except Exception as exc:  # noqa: BLE001 - the loop must survive anything
            self.service.log.error(f"internal error in the solve loop: {exc!r}")
            outcome = None
        if outcome is not None:
            self.modes.note_input(data, stamp_ns)
            try:
                self._deliver(outcome)
            except Exception as exc:  # noqa: BLE001
                self.service.log.error(f"internal error in the solve loop: {exc!r}")
        with self._cond:
            item, self._pending = self._pending, None
            if item is None or self._closed:
                self._busy = False
                item = None
        if item is None:
            return outcome is not None
        if outcome is None:             # replaced, unsolved, by an input that arrived meanwhile
            self.stats.record_dropped(1)
        self._drain(item)
        return True

    def _wait_or_replace(self, item) -> None:
        with self._cond:
            replaced = self._pending is not None
            self._pending = item
            self._cond.notify()
        if replaced:
            self.stats.record_dropped(1)

    def _drain(self, item) -> None:
        """Solve ``item``, then every input that arrived meanwhile, newest first; clears busy."""
        self.realtime.enter()
        while item is not None:
            try:
                self._solve(item)
            except Exception as exc:  # noqa: BLE001 - the loop must survive anything
                self.service.log.error(f"internal error in the solve loop: {exc!r}")
            with self._cond:
                item, self._pending = self._pending, None
                if item is None or self._closed:
                    self._busy = False
                    item = None

    def _solve(self, item) -> None:
        self._deliver(self.service.solve(*item))

    def _deliver(self, outcome) -> None:
        """Publish an outcome's pose, then account for it (the statistics wait until the pose is out) and hand
        it to the extras."""
        if outcome.pose is None:
            return
        try:
            self.publish(outcome.pose)
        except Exception as exc:  # noqa: BLE001 - a failed publish must not stop the loop
            self.service.log.error(f"publishing the pose failed: {exc!r}")
            return
        finally:
            self.service.account(outcome)
        if self.extras is not None and self.service.extras_on():
            t0 = time.perf_counter()
            self.extras.put(outcome)
            self.stats.record_extras_handoff(time.perf_counter() - t0)

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._closed and (self._pending is None or self._busy):
                    self._cond.wait(0.1)
                if self._closed:
                    return
                item, self._pending = self._pending, None
                self._busy = True
            self._drain(item)

    def stop(self, timeout: float = 2.0) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout)
        if self.extras is not None:
            self.extras.stop(timeout)


class AssemblyModesLoop:
    """The thread both transports use for ``~/request_assembly_modes``: each request takes the
    last input received at that moment; the newest pending request is computed (by ``solve``,
    normally a :class:`~glpma_ros.node.modes_worker.ModesWorker` process, so that the solve loop
    keeps its latency) and its :class:`PoseArrayOutput` published.  A request arriving while
    another waits replaces it (counted as coalesced); one arriving during a computation is
    answered by a computation of its own afterwards."""

    def __init__(self, modes: AssemblyModes, publish, solve=None, name: str = "glpma_fk-assembly-modes", *, log):
        """``modes``: the node's :class:`~glpma_ros.node.assembly_modes.AssemblyModes` (last input,
        figures); ``solve(legs, runs, seed, leg_noise_std)``: default a new
        :class:`~glpma_ros.node.modes_worker.ModesWorker` (started by :meth:`start`, stopped by
        :meth:`stop`); ``log``: anything with ``info/warning/error(str)``."""
        self.modes = modes
        self.log = log
        self.publish = publish
        self._owned = solve is None
        self.solve = modes.worker() if solve is None else solve
        self.mailbox = LatestInput()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> "AssemblyModesLoop":
        if self._owned:
            self.solve.start()          # the child warms up while the node does
        self._thread.start()
        return self

    def request(self, stamp_ns: int) -> None:
        """Called by the transport on arrival of a request, ``stamp_ns`` = its arrival time."""
        if self.mailbox.put((int(stamp_ns), self.modes.last_input)):
            self.modes.note(coalesced=1)

    def _run(self) -> None:
        log, modes = self.log, self.modes
        while not self._stop.is_set():
            item = self.mailbox.get(timeout=0.1)
            if item is None:
                continue
            stamp_ns, last_input = item
            try:
                result = modes.compute(stamp_ns, last_input, solve=self.solve)
            except InputError as exc:
                modes.note(failure=str(exc))
                log.warning(f"assembly modes not computed: {exc}")
                continue
            except Exception as exc:  # noqa: BLE001 - the node must survive anything
                modes.note(failure=f"internal error: {exc}")
                log.error(f"assembly modes failed: {exc!r}")
                continue
            modes.note(result)
            log.info(f"assembly modes: {len(result.poses)} real assembly modes in {result.elapsed_s:.3f} s "
                     f"from {result.starts} starts")
            try:
                self.publish(result)
            except Exception as exc:  # noqa: BLE001
                log.error(f"publishing the assembly modes failed: {exc!r}")

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        self.mailbox.close()
        if self._owned:
            self.solve.close()
        self._thread.join(timeout)


#: the report thread's sleep between two stages of a report: it releases the interpreter, so that
#: a solving thread waiting for it takes it (the thread otherwise keeps it until it blocks, or for
#: up to ``sys.getswitchinterval()``, 5 ms); a report takes a few of these, once a period
REPORT_PAUSE_S = 50e-6


def pause_report() -> None:
    """What the report thread does between two stages of a report: sleep :data:`REPORT_PAUSE_S`."""
    time.sleep(REPORT_PAUSE_S)


class ReportLoop:
    """Publishes the report of a :class:`~glpma_ros.node.diagnostics.Diagnostics` every ``period_s``
    from a thread of its own, so that a
    report -- taken from snapshots, its formatting and its message built outside every lock of
    the service -- is never on the solving thread's path (in the rclpy node a timer would run it
    in the executor's thread, between two inputs).  Between the stages of a report (and before
    its message is built) the thread sleeps :data:`REPORT_PAUSE_S`: a solving thread waits at
    most one stage for the interpreter."""

    def __init__(self, diagnostics: Diagnostics, publish, period_s: float, name: str = "glpma_fk-diagnostics", *,
                 log):
        """``diagnostics``: the service's reporter (``service.reporter``); ``publish(DiagnosticReport)``:
        converts and writes the report (a failure is logged in ``log``)."""
        self.diagnostics = diagnostics
        self.log = log
        self.publish = publish
        self.period_s = float(period_s)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> "ReportLoop":
        self._thread.start()
        return self

    def _run(self) -> None:
        next_report = time.monotonic()
        while not self._stop.wait(max(0.0, next_report - time.monotonic())):
            try:
                report = self.diagnostics.report(pause=pause_report)
                pause_report()
                self.publish(report)
            except Exception as exc:  # noqa: BLE001 - a failed report must not end the reports
                self.log.warning(f"publishing diagnostics failed: {exc!r}")
            next_report = max(next_report + self.period_s, time.monotonic())

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout)


def node_loops(service: FkService, *, publish_pose, publish_extras, subscribed, publish_modes, publish_report,
               modes_solve=None, extras_thread: bool = True) -> tuple[SolveLoop, AssemblyModesLoop, ReportLoop]:
    """The loops of a node over ``service``, not started, handed the collaborators each reads; the transport
    gives how its outputs are written (``publish_*``), whether an extra output has subscribers, whether they
    are written by a thread of their own (``extras_thread``, :class:`ExtrasLoop`) and, for the assembly modes,
    where they are computed (``modes_solve``, default in the node's process)."""
    return (SolveLoop(service, publish_pose, publish_extras=publish_extras, subscribed=subscribed,
                      stats=service.stats, modes=service.modes, extras_thread=extras_thread),
            AssemblyModesLoop(service.modes, publish_modes, solve=modes_solve, log=service.log),
            ReportLoop(service.reporter, publish_report, service.params["diagnostics_period_s"], log=service.log))
