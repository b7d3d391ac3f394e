"""The transport floor: a stand-in for the ``glpma_fk`` node over Cyclone DDS that only echoes.

It reads ``leg_lengths`` as the DDS node does (:mod:`glpma_ros.node.dds.node`): a wait set on
the reader (:func:`~glpma_ros.node.dds.endpoints.reader_waitset`), the samples taken raw in a
batch (:func:`~glpma_ros.node.dds.cdr.take_raw`), the arrival time taken at once, the newest
sample kept (the others count as dropped) and its legs read with ``struct``; for it, it writes a
``pose_estimate`` stamped with that arrival time (:class:`~glpma_ros.node.dds.cdr.Encoder`,
:class:`~glpma_ros.node.dds.cdr.RawWriter`) -- no solve, no estimator, no extra outputs, no
thread hand-off.  From legs written to pose read, a client measures against it what Python and
Cyclone DDS cost on the machine: the least a Python node on this transport can reach.  The pose
carries the leg lengths (metres) it answers in its seven numbers, position then orientation
(:func:`legs_of`; zeros after the last leg): it is no pose, and a reader can tell which input
it answers.

Run: ``python -m glpma_tools.sim.echo_node --ros-args [--params-file FILE] [-p qos_depth:=N]``
(``qos_depth`` and ``frame_id`` as the node reads them); prints a ``ready`` line on stdout,
stops at SIGINT or SIGTERM with a line ``stopped: received N, echoed N, dropped N`` on stderr.
"""
from __future__ import annotations

import signal
import sys
import threading
import time

from cyclonedds.util import duration

from glpma_ros.errors import InputError
from glpma_ros.node.dds import cdr, endpoints
from glpma_ros.node.dds.messages import Float64MultiArray, PoseStamped
from glpma_ros.node.dds.node import TAKE_BATCH  # the node's batch
from glpma_ros.node.ros_args import node_values

#: the wait set's timeout (s): how often the loop looks at the stop flag
WAIT_S = 0.2
#: numbers of a pose: position (3) and orientation (4)
POSE_NUMBERS = 7


def legs_of(pose, n_legs: int) -> tuple:
    """The ``n_legs`` leg lengths an echoed pose carries (its position, then its orientation)."""
    _, _, _, position, orientation = pose
    return (tuple(position) + tuple(orientation))[:n_legs]


class Echo:
    """The reader, the writer and the loop of the echo."""

    def __init__(self, participant, depth: int, frame_id: str):
        self.reader = participant.reader(endpoints.LEG_LENGTHS, Float64MultiArray, depth)
        self.writer = participant.writer(endpoints.POSE_ESTIMATE, PoseStamped, depth)
        self._raw = cdr.RawWriter(self.writer)
        self._encode = cdr.Encoder()
        self.frame_id = frame_id
        self.waitset, self.guard = endpoints.reader_waitset(participant, [self.reader])
        self.received = self.echoed = self.dropped = 0
        self.stop = threading.Event()

    def run(self) -> None:

        timeout = duration(seconds=WAIT_S)
        while not self.stop.is_set():
            self.waitset.wait(timeout)
            samples = cdr.take_raw(self.reader, TAKE_BATCH)
            arrival_ns = time.time_ns()
            valid = [data for data, info in samples if info.valid_data]
            if not valid:
                continue
            self.received += len(valid)
            self.dropped += len(valid) - 1
            numbers = (cdr.float64_multi_array_data(valid[-1]) + (0.0,) * POSE_NUMBERS)[:POSE_NUMBERS]
            self._raw.write(self._encode.pose_stamped(arrival_ns, self.frame_id, numbers[:3], numbers[3:]))
            self.echoed += 1

    def close(self) -> None:
        self.stop.set()
        self.guard.set(True)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        values, _, _ = node_values(argv)
    except InputError as exc:
        print(f"echo_node: error: {exc}", file=sys.stderr)
        return 2
    echo = Echo(endpoints.Participant(), values["qos_depth"], values["frame_id"])
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: echo.close())
    print(f"[echo] ready: domain {endpoints.domain_id_from_env()}", flush=True)
    echo.run()
    print(f"[echo] stopped: received {echo.received}, echoed {echo.echoed}, dropped {echo.dropped}",
          file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
