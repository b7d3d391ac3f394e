"""The rclpy node's input taken off the executor, by a thread that waits on the input subscription alone.

rclpy's ``SingleThreadedExecutor`` rebuilds its wait set from every entity of the node on each wake-up (the
input and request subscriptions, the parameter and type-description services, guard conditions), enters
each handle, then wraps the ready callback in a task: several hundred microseconds of Python per input on
this project's 2-core machine, as much as the rest of the node's path (BENCHMARKS.md, "Extra outputs and
the transport path", part 4).  :class:`InputThread` waits on a wait set of two entities -- the input
subscription and a guard condition that stops it -- built once and refilled per wake-up, with the
interpreter lock released in ``rcl_wait``; it takes every sample waiting (raw bytes), and hands the newest
to the node with the count of the ones passed over (the node's newest-input rule) -- or, for a subscriber
that wants them all (the bench's client taking poses), each sample in the order taken.  The subscription is
created by the node as any other (remapping, QoS overrides and ``ros2 node info`` see it) in a
:class:`NotByExecutor` callback group, which no executor waits on or runs.  The executor keeps the
parameters, services, the assembly-modes request and the lifecycle transitions.

``rclpy`` has no public wait set: the one of ``rclpy.impl.implementation_singleton`` (what every rclpy
executor uses) is used here as its executors use it, each handle held while it is in the wait set.
Importable only where rclpy is.
"""
from __future__ import annotations

import threading

from rclpy.callback_groups import CallbackGroup
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

#: seconds a wait lasts at most before the thread looks at its stop flag (a stop also wakes it at once)
WAIT_TIMEOUT_S = 0.5
#: entities of the wait set: one subscription, one guard condition, no timer, client, service or event
WAIT_SET_SIZES = (1, 1, 0, 0, 0, 0)


def taken_by_input_thread(_msg) -> None:
    """The callback of a subscription in a :class:`NotByExecutor` group: rclpy requires one; no executor
    calls it (its samples go to the :class:`InputThread`'s handler)."""


class NotByExecutor(CallbackGroup):
    """A callback group no executor runs: its subscription is waited on and taken by an :class:`InputThread`."""

    def can_execute(self, entity) -> bool:
        return False

    def beginning_execution(self, entity) -> bool:
        return False

    def ending_execution(self, entity) -> None:
        pass


def subscribe_taken_by_thread(create_subscription, msg_type, topic: str, qos, context, handle, *,
                              newest_only: bool = True, **options):
    """A raw subscription (``create_subscription(msg_type, topic, callback, qos, raw=True, ...)``, rclpy's
    signature, ``options`` passed on) in a :class:`NotByExecutor` group, and the started :class:`InputThread`
    that takes its samples and calls ``handle(data, passed_over)`` (``newest_only``: see :class:`InputThread`)."""
    subscription = create_subscription(msg_type, topic, taken_by_input_thread, qos, raw=True,
                                       callback_group=NotByExecutor(), **options)
    return subscription, InputThread(subscription, context, handle, newest_only=newest_only).start()


class InputThread:
    """Waits on ``subscription`` (created with a :class:`NotByExecutor` group, ``raw=True``) and calls
    ``handle(data, passed_over)`` with the newest sample taken and the number of older ones taken with it;
    with ``newest_only=False``, ``handle(data, 0)`` for every sample taken, oldest first."""

    def __init__(self, subscription, context, handle, name: str = "glpma_fk-input", *, newest_only: bool = True):
        self.newest_only = newest_only
        self.subscription = subscription
        self.context = context
        self.handle = handle
        self._stop = threading.Event()
        self._guard = GuardCondition(None, None, context=context)
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def start(self) -> "InputThread":
        self._thread.start()
        return self

    def stop(self, timeout: float = 2.0) -> None:
        """End the thread (after the input it is handling, if any); idempotent."""
        self._stop.set()
        if self._thread.is_alive():
            try:
                self._guard.trigger()
            except Exception:  # noqa: BLE001 - the context is gone: the wait returns by its timeout
                pass
            if threading.current_thread() is not self._thread:
                self._thread.join(timeout)

    def _take(self):
        sub = self.subscription
        with sub.handle:
            taken = sub.handle.take_message(sub.msg_type, sub.raw)
        return None if taken is None else taken[0]

    def _take_newest(self):
        newest, taken_count = None, 0
        while (data := self._take()) is not None:
            newest, taken_count = data, taken_count + 1
        return newest, taken_count

    def _take_each(self) -> None:
        while (data := self._take()) is not None:
            self.handle(data, 0)

    def _wait(self, wait_set) -> bool:
        """Wait for a sample or the stop; False when the context or the subscription is gone."""
        sub = self.subscription
        try:
            with self.context.handle, sub.handle, self._guard.handle:
                wait_set.clear_entities()
                wait_set.add_subscription(sub.handle)
                wait_set.add_guard_condition(self._guard.handle)
                wait_set.wait(int(WAIT_TIMEOUT_S * 1e9))
        except Exception:  # noqa: BLE001 - shut down or destroyed under the wait: the thread ends
            return False
        return True

    def _run(self) -> None:
        with self.context.handle:
            wait_set = _rclpy.WaitSet(*WAIT_SET_SIZES, self.context.handle)
        while not self._stop.is_set() and self._wait(wait_set):
            if self._stop.is_set():
                break
            try:
                if not self.newest_only:
                    self._take_each()
                    continue
                newest, count = self._take_newest()
            except Exception:  # noqa: BLE001 - the subscription was destroyed: the thread ends
                break
            if newest is not None:
                self.handle(newest, count - 1)
