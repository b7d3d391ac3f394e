"""The threads both transports share: :class:`SolveLoop` solves the newest pending input (an
input replaced before it was picked up counts as dropped) and publishes its pose;
:class:`AssemblyModesLoop` answers ``~/request_assembly_modes`` off the real-time path."""
from __future__ import annotations

import threading
import time

from ..errors import InputError
from .service import FkService, JointStateInput


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


class SolveLoop:
    """The worker thread both transports use: solve the newest input, publish its pose."""

    def __init__(self, service: FkService, publish, name: str = "glpma_fk-solver"):
        self.service = service
        self.publish = publish
        self.mailbox = LatestInput()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> "SolveLoop":
        self._thread.start()
        return self

    def submit(self, legs_m, stamp_ns: int) -> None:
        """Called by the transport on arrival of leg lengths (metres), ``stamp_ns`` = arrival time."""
        arrival = time.perf_counter()
        self.service.note_input(legs_m, stamp_ns)
        if self.mailbox.put((legs_m, int(stamp_ns), arrival)):
            self.service.note_dropped(1)

    def submit_joint_state(self, names, positions, stamp_ns: int) -> None:
        """Called by the transport on arrival of a JointState, ``stamp_ns`` = its header.stamp.
        The legs are picked out by the solver thread (a rejection is counted there)."""
        self.submit(JointStateInput(tuple(names), tuple(positions)), stamp_ns)

    def _run(self) -> None:
        while not self._stop.is_set():
            item = self.mailbox.get(timeout=0.1)
            if item is None:
                continue
            outcome = self.service.handle(*item)
            if outcome.pose is not None:
                try:
                    self.publish(outcome.pose)
                except Exception as exc:  # noqa: BLE001 - a failed publish must not stop the loop
                    self.service.log.error(f"publishing the pose failed: {exc!r}")

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        self.mailbox.close()
        self._thread.join(timeout)


class AssemblyModesLoop:
    """The thread both transports use for ``~/request_assembly_modes``: each request takes the
    last input received at that moment; the newest pending request is computed (by ``solve``,
    normally a :class:`~glpma_ros.node.modes_worker.ModesWorker` process, so that the solve loop
    keeps its latency) and its :class:`PoseArrayOutput` published.  A request arriving while
    another waits replaces it (counted as coalesced); one arriving during a computation is
    answered by a computation of its own afterwards."""

    def __init__(self, service: FkService, publish, solve=None, name: str = "glpma_fk-assembly-modes"):
        """``solve(legs, runs, seed)``: default a new :class:`~glpma_ros.node.modes_worker.ModesWorker`
        (started by :meth:`start`, stopped by :meth:`stop`)."""
        self.service = service
        self.publish = publish
        self._owned = solve is None
        self.solve = service.modes_worker() if solve is None else solve
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
        if self.mailbox.put((int(stamp_ns), self.service._last_input)):
            self.service.note_assembly_modes(coalesced=1)

    def _run(self) -> None:
        log = self.service.log
        while not self._stop.is_set():
            item = self.mailbox.get(timeout=0.1)
            if item is None:
                continue
            stamp_ns, last_input = item
            try:
                result = self.service.assembly_modes(stamp_ns, last_input, solve=self.solve)
            except InputError as exc:
                self.service.note_assembly_modes(failure=str(exc))
                log.warning(f"assembly modes not computed: {exc}")
                continue
            except Exception as exc:  # noqa: BLE001 - the node must survive anything
                self.service.note_assembly_modes(failure=f"internal error: {exc}")
                log.error(f"assembly modes failed: {exc!r}")
                continue
            self.service.note_assembly_modes(result)
            log.info(f"assembly modes: {len(result.poses)} real assembly modes in {result.elapsed_s:.3f} s")
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
