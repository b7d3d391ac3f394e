"""The controller side of a simulated robot, over Cyclone DDS: one participant that writes leg
lengths (``leg_lengths``, or ``joint_states`` with the legs among other joints), listens to the
node's ``pose_estimate`` and ``/diagnostics`` on a thread, and can ask for the assembly modes.
Lengths go out in metres (REP 103): the only place the tools convert the legs for the wire.

The controller stays out of the latency it measures: an input is serialized before its send time
is taken and written as bytes, and a pose is taken as bytes, its receive time taken at once and
its fields read with ``struct`` (the binding's Python (de)serializers would add their own time to
every message's)."""
from __future__ import annotations

import gc
import struct
import threading
import time
from dataclasses import dataclass

import numpy as np
from cyclonedds.core import Entity
from cyclonedds.util import duration

from glpma_ros.node.dds import cdr, endpoints
from glpma_ros.node.dds.messages import (
    DiagnosticArray,
    Empty,
    Float64MultiArray,
    Header,
    JointState,
    MultiArrayDimension,
    MultiArrayLayout,
    PoseArray,
    PoseStamped,
    Time,
)
from glpma_ros.node.params import INPUT_FLOAT64_MULTI_ARRAY, INPUT_JOINT_STATE, INPUT_TYPES
from glpma_ros.node.service import default_joint_names

#: other joints of the robot sent with the legs in a JointState (name, position)
EXTRA_JOINTS = (("gripper_finger", 0.02), ("wrist_roll", -0.7), ("base_yaw", 1.3))
#: the node's counters on ``/diagnostics``
COUNTERS = {"received": "inputs received", "solved": "inputs solved", "rejected": "inputs rejected",
            "dropped": "inputs dropped", "deadline_misses": "deadline misses"}


@dataclass
class Sent:
    """One input written: when, its legs (config unit) and the true pose (metres, quaternion)."""

    send_ns: int
    legs: np.ndarray
    position_m: np.ndarray
    quaternion: np.ndarray


_STAMP_AND_FRAME = struct.Struct("<iII")
_POSE = struct.Struct("<7d")


def pose_stamped_fields(buf) -> tuple[int, str, np.ndarray, np.ndarray]:
    """``(stamp ns, frame_id, position (3,), quaternion [x, y, z, w] (4,))`` of a
    ``geometry_msgs/PoseStamped`` in its wire form (XCDR1; the binding reads other encodings)."""
    if not cdr.little_endian_cdr(buf):
        s = PoseStamped.deserialize(bytes(buf))
        p, q = s.pose.position, s.pose.orientation
        return s.header.stamp.to_ns(), s.header.frame_id, np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w])
    sec, nanosec, size = _STAMP_AND_FRAME.unpack_from(buf, cdr.HEADER_SIZE)
    start = cdr.HEADER_SIZE + _STAMP_AND_FRAME.size
    offset = start + size
    offset += -(offset - cdr.HEADER_SIZE) % 8                   # the doubles are aligned to 8 in the payload
    values = _POSE.unpack_from(buf, offset)
    return (sec * 1_000_000_000 + nanosec, bytes(buf[start:start + size - 1]).decode(), np.array(values[:3]),
            np.array(values[3:]))


def counters(values: dict) -> dict:
    """The node's input counters from a ``/diagnostics`` report's values."""
    return {k: int(values.get(key, 0)) for k, key in COUNTERS.items()}


def diff(after: dict, before: dict | None) -> dict:
    """Counter differences over a phase (``before`` None: since the node started)."""
    return {k: v - (before or {}).get(k, 0) for k, v in after.items()}


def starts(values: dict) -> dict:
    """How many solves started warm, widened and cold, from a ``/diagnostics`` report's values."""
    warm, widened, cold = (int(v) for v in values.get("starts warm/widened/cold", "0/0/0").split("/"))
    return {"warm": warm, "widened": widened, "cold": cold}


class PoseListener:
    """Takes ``pose_estimate`` (and the node's ``/diagnostics``) on a thread, with receive times."""

    def __init__(self, participant, depth: int):
        self.reader = participant.reader(endpoints.POSE_ESTIMATE, PoseStamped, depth)
        self.diag_reader = participant.reader(endpoints.DIAGNOSTICS, DiagnosticArray, depth)
        self.poses: list = []            # (recv_ns, stamp_ns, frame_id, position (3,), quaternion (4,))
        self.diagnostics: dict | None = None
        self.diagnostics_stamp_ns = 0
        self._stop = False
        self._waitset, self._guard = endpoints.reader_waitset(participant, [self.reader, self.diag_reader])
        self._thread = threading.Thread(target=self._run, name="mock-pose-listener", daemon=True)
        self._thread.start()

    def _run(self):

        while not self._stop:
            self._waitset.wait(duration(milliseconds=100))
            samples = cdr.take_raw(self.reader, 256)
            recv_ns = time.time_ns()
            for data, info in samples:
                if info.valid_data:
                    self.poses.append((recv_ns, *pose_stamped_fields(data)))
            for d in self.diag_reader.take(64):
                if isinstance(d, DiagnosticArray) and d.status:
                    status = d.status[0]
                    self.diagnostics = {"level": int(status.level), "message": status.message,
                                        "values": {kv.key: kv.value for kv in status.values}}
                    self.diagnostics_stamp_ns = d.header.stamp.to_ns()

    def close(self):
        self._stop = True
        self._guard.set(True)
        self._thread.join(2.0)


class ModesClient:
    """Sends ``~/request_assembly_modes`` one after the other (the next once the previous is
    answered and ``period_s`` has passed) and collects the ``~/assembly_modes`` answers."""

    def __init__(self, participant):
        self._empty = Empty
        self.writer = participant.writer(endpoints.REQUEST_ASSEMBLY_MODES, Empty, 1)
        self.reader = participant.reader(endpoints.ASSEMBLY_MODES, PoseArray, 1, transient_local=True)
        self.endpoints = [self.writer, self.reader]
        self.requested = 0
        self.pending_ns = None          # send time of the request being answered
        self.last_ns = 0
        self.answers = []               # (modes, seconds from request to answer)
        self.windows = []               # (request ns, answer ns)

    def poll(self, now_ns: int, period_s: float | None) -> None:
        for msg in self.reader.take(4):
            if hasattr(msg, "poses") and self.pending_ns is not None:
                done = time.time_ns()
                self.answers.append((len(msg.poses), (done - self.pending_ns) * 1e-9))
                self.windows.append((self.pending_ns, done))
                self.pending_ns = None
        if period_s is not None and self.pending_ns is None and now_ns - self.last_ns >= period_s * 1e9:
            self.writer.write(self._empty())
            self.requested += 1
            self.pending_ns = self.last_ns = now_ns

    def busy_at(self, t_ns: int) -> bool:
        return any(a <= t_ns <= b for a, b in self.windows)


class Controller:
    """One DDS participant of a simulated controller of ``model``'s manipulator.

    ``input_type`` ``joint_state``: each ``joint_states`` message holds the legs under
    ``joint_names`` (default the node's, ``leg_1`` .. ``leg_n``) among :data:`EXTRA_JOINTS`, in a
    new random order every time, ``header.stamp`` = its send time."""

    def __init__(self, model, domain_id: int | None = None, depth: int = 10, listen_depth: int = 1000,
                 input_type: str = INPUT_FLOAT64_MULTI_ARRAY, joint_names=None, modes: bool = False):
        if input_type not in INPUT_TYPES:
            raise ValueError(f"input_type must be one of {', '.join(INPUT_TYPES)}, got {input_type!r}")
        self.names = list(joint_names) if joint_names else default_joint_names(model.n_legs)
        if len(self.names) != model.n_legs:
            raise ValueError(f"joint_names must name the {model.n_legs} legs, got {len(self.names)} names")
        self.model = model
        self.mpu = float(model.metres_per_unit)
        self.joint_state = input_type == INPUT_JOINT_STATE
        self.participant = endpoints.Participant(domain_id)
        if self.joint_state:
            self.writer = self.participant.writer(endpoints.JOINT_STATES, JointState, depth)
        else:
            self.writer = self.participant.writer(endpoints.LEG_LENGTHS, Float64MultiArray, depth)
        self.raw_writer = cdr.RawWriter(self.writer)
        self.listener = PoseListener(self.participant, listen_depth)
        self.modes = ModesClient(self.participant) if modes else None
        self._layout = MultiArrayLayout(dim=[MultiArrayDimension(label="legs", size=model.n_legs,
                                                                 stride=model.n_legs)])
        self._shuffle = np.random.default_rng(0)

    @property
    def endpoints(self) -> list:
        return [self.writer, self.listener.reader, self.listener.diag_reader] + (
            self.modes.endpoints if self.modes else [])

    def wait_for_node(self, timeout: float) -> float:
        """Seconds until the node's endpoints matched ours; :class:`TimeoutError` after ``timeout``."""
        t0 = time.monotonic()
        if not endpoints.wait_for_match(self.endpoints, timeout):
            raise TimeoutError(f"no glpma_fk node on ROS domain {self.participant.domain_id} within {timeout:g} s "
                               "(is it running with the same CYCLONEDDS_URI?)")
        return time.monotonic() - t0

    def message(self, legs):
        """(the message carrying ``legs`` (config unit) in metres, its stamp in ns or None)."""
        legs_m = (np.asarray(legs, dtype=float) * self.mpu).tolist()
        if not self.joint_state:
            return Float64MultiArray(layout=self._layout, data=legs_m), None
        joints = list(zip(self.names, legs_m)) + list(EXTRA_JOINTS)
        order = self._shuffle.permutation(len(joints))
        stamp_ns = time.time_ns()
        return JointState(header=Header(stamp=Time.from_ns(stamp_ns), frame_id=""),
                          name=[joints[k][0] for k in order], position=[joints[k][1] for k in order]), stamp_ns

    def encoded(self, legs) -> tuple[bytes, int | None]:
        """:meth:`message` in its wire form, as ``DataWriter.write`` would send it."""
        msg, stamp_ns = self.message(legs)
        data = msg.serialize()
        return data.ljust(-(-len(data) // 4) * 4, b"\0"), stamp_ns

    def send(self, plan, t0: float, n: int, rate_hz: float | None, dt: float, stop: threading.Event | None = None,
             each=None) -> tuple[list, int]:
        """Write ``n`` samples of ``plan`` (:class:`.trajectories.Plan`) from trajectory time ``t0``,
        ``dt`` apart, paced at ``rate_hz`` in wall time, or as fast as possible when ``rate_hz`` is
        None (the messages are then prepared beforehand).  The messages carry ``plan.measured`` legs (a
        faulty sensor's step, if any); the records keep the true legs.  ``each(i, sent)`` is called after every
        write, if given; ``stop`` ends the sending early.  Returns ([:class:`Sent`], late sends)."""
        sent, late = [], 0
        if rate_hz is None:
            samples = [plan.sample(t0 + i * dt) for i in range(n)]
            prepared = [self.encoded(plan.measured(s[0], t0 + i * dt)) for i, s in enumerate(samples)]
            for (legs, pos, q), (data, stamp_ns) in zip(samples, prepared):
                send_ns = stamp_ns or time.time_ns()
                self.raw_writer.write(data)
                sent.append(Sent(send_ns, legs, pos, q))
            return sent, 0
        start = time.perf_counter()
        for i in range(n):
            if stop is not None and stop.is_set():
                break
            delay = start + i / rate_hz - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            elif delay < -1.0 / rate_hz:
                late += 1
            legs, pos, q = plan.sample(t0 + i * dt)
            data, stamp_ns = self.encoded(plan.measured(legs, t0 + i * dt))
            send_ns = stamp_ns or time.time_ns()
            self.raw_writer.write(data)
            sent.append(Sent(send_ns, legs, pos, q))
            if each is not None:
                each(i, sent)
        return sent, late

    def diagnostics_after(self, t_ns: int, timeout: float, stable: bool = True) -> dict | None:
        """Values of the first ``/diagnostics`` report stamped after ``t_ns`` -- with ``stable``, of
        the first two consecutive such reports with the same counters (the node is idle, so its
        counters add up); None when none came within ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        last_stamp, previous = t_ns, None
        while time.monotonic() < deadline:
            stamp, diag = self.listener.diagnostics_stamp_ns, self.listener.diagnostics
            if stamp > last_stamp and diag is not None:
                last_stamp = stamp
                values = diag["values"]
                if not stable or (previous is not None and counters(previous) == counters(values)):
                    return values
                previous = values
            time.sleep(0.01)
        return None

    def counters_before(self, timeout: float) -> dict | None:
        """The node's counters before this controller sends: those of its first report when it has
        received nothing yet, else those of a stable report (it is idle); None without a report
        within ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while self.listener.diagnostics is None and time.monotonic() < deadline:
            time.sleep(0.01)
        if self.listener.diagnostics is None:
            return None
        first = counters(self.listener.diagnostics["values"])
        if first["received"] == 0:
            return first
        values = self.diagnostics_after(0, max(0.0, deadline - time.monotonic()))
        return None if values is None else counters(values)

    def close(self) -> None:
        """Delete the participant and everything in it (a controller that goes away)."""
        self.listener.close()
        entities = [self.writer, self.listener.reader, self.listener.diag_reader, self.participant.dp]
        # the binding keeps the handles and its registry of entities private; it deletes an entity only
        # when the last Python reference goes, which a test's leftover reference would otherwise prevent
        refs = [e._ref for e in entities + (self.modes.endpoints if self.modes else [])]  # noqa: SLF001
        self.writer = self.raw_writer = self.listener = self.participant = self.modes = None
        del entities
        gc.collect()
        for ref in refs:             # still referenced somewhere: delete explicitly
            entity = Entity._entities.get(ref)  # noqa: SLF001
            if entity is not None:
                entity.__del__()
