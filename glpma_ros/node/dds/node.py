"""The ``glpma_fk`` node over plain Eclipse Cyclone DDS (no ROS 2 installation needed).

Same topics, types, QoS and parameters as the rclpy node (``ros_node.py``);
both run :class:`~glpma_ros.node.service.FkService` through
:class:`~glpma_ros.node.loops.SolveLoop` and
:class:`~glpma_ros.node.loops.AssemblyModesLoop`.

Threads.  Two reader threads take turns as the *leader* (leader/followers, Schmidt et al.,
*Pattern-Oriented Software Architecture* vol. 2): the leader waits for leg lengths (or joint
states) and assembly-modes requests, takes them (the newest input wins, older ones count as
dropped), hands the leadership over and solves the input itself, then publishes the pose,
unless a solve is in progress, in which case the input waits for it
(:meth:`SolveLoop.offer <glpma_ros.node.loops.SolveLoop.offer>`).  So an input goes from the
DDS reader to the solver without a thread switch, and inputs arriving during a solve are
still taken (and counted) at once.  TF, covariance, twist and markers of each pose are built
and written by the extras thread (:class:`~glpma_ros.node.loops.ExtrasLoop`), only for the
topics some reader is matched with.  The hot messages are encoded and decoded by
:mod:`.cdr` rather than by the binding's generic serializer.  The assembly-modes thread hands
requests to its worker process and publishes the PoseArray; the report thread
(:class:`~glpma_ros.node.loops.ReportLoop`) publishes ``/diagnostics`` every
``diagnostics_period_s``; the main thread handles signals (SIGINT and SIGTERM stop
the node, SIGHUP re-reads the ``--ros-args`` parameters, i.e. the params files, and applies
the changed ones).

Run: ``python -m glpma_ros.node.dds.node --ros-args --params-file config/params_3rpr.yaml``.
Prints one line ``[glpma_fk] ready: ...`` on stdout once it can take inputs;
logs go to stderr.
"""
from __future__ import annotations

import logging
import signal
import sys
import threading
import time

from cyclonedds.util import duration

from ...errors import GlpmaError, InputError
from .. import params as P
from .. import qos
from ..loops import node_loops, pause_report
from ..ros_args import node_values, parse_ros_args, remapped, split_transport
from ..service import FkService, JointStateInput
from . import cdr, endpoints
from .messages import (
    DiagnosticArray,
    Empty,
    Float64MultiArray,
    Header,
    JointState,
    MarkerArray,
    Point,
    Pose,
    PoseArray,
    PoseStamped,
    PoseWithCovarianceStamped,
    Quaternion,
    TFMessage,
    Time,
    TwistStamped,
)
from .security import check_dds_transport

LOG_FORMAT = "[%(levelname)s] [%(created).3f] [%(name)s]: %(message)s"
#: samples taken per read; the newest is solved, the others count as dropped
TAKE_BATCH = 256
#: threads taking turns at reading and solving (one reads while the other solves)
READER_THREADS = 2
#: seconds between two looks of the main thread for a SIGHUP reload (a reload waits at most this)
RELOAD_POLL_S = 0.25


def pose_array_message(modes) -> PoseArray:
    """:class:`~glpma_ros.node.assembly_modes.PoseArrayOutput` -> ``geometry_msgs/PoseArray``."""
    return PoseArray(header=Header(stamp=Time.from_ns(modes.stamp_ns), frame_id=modes.frame_id),
                     poses=[Pose(position=Point(*position), orientation=Quaternion(*orientation))
                            for position, orientation in modes.poses])


class DdsNode:
    """Endpoints and threads around one :class:`FkService`."""

    def __init__(self, service: FkService, participant: endpoints.Participant, remaps: dict | None = None,
                 modes_solve=None, qos_overrides: dict | None = None):
        """``modes_solve``: how assembly modes are computed (default: a worker process);
        ``qos_overrides``: the ``qos_overrides.*`` parameters (:mod:`glpma_ros.node.qos`)."""
        self.service = service
        self.participant = participant
        remaps = remaps or {}

        def topic(name):
            return endpoints.expand_topic_name(remapped(name, remaps), service.node_name)

        self.joint_state = service.input_type == P.INPUT_JOINT_STATE
        self.input_name = service.input_topic
        self.qos, qos_warnings = node_qos(service, remaps, qos_overrides or {})
        for warning in qos_warnings:
            service.log.warning(warning)
        pub, sub = self.qos_of(qos.PUBLISHER), self.qos_of(qos.SUBSCRIPTION)
        self.topics = {name: topic(name) for name in (self.input_name, endpoints.POSE_ESTIMATE,
                                                       endpoints.POSE_ESTIMATE_COV, endpoints.TWIST_ESTIMATE,
                                                       endpoints.TF, endpoints.MARKERS,
                                                       endpoints.MECHANISM_JOINT_STATES,
                                                       endpoints.DIAGNOSTICS, endpoints.ASSEMBLY_MODES,
                                                       endpoints.REQUEST_ASSEMBLY_MODES)}
        # every output has its writer from the start: the publish_* parameters switch them at runtime
        self.pose_writer = participant.writer(self.topics[endpoints.POSE_ESTIMATE], PoseStamped,
                                              qos=pub(endpoints.POSE_ESTIMATE))
        self.tf_writer = participant.writer(self.topics[endpoints.TF], TFMessage, qos=pub(endpoints.TF))
        self.cov_writer = participant.writer(self.topics[endpoints.POSE_ESTIMATE_COV], PoseWithCovarianceStamped,
                                             qos=pub(endpoints.POSE_ESTIMATE_COV))
        self.twist_writer = participant.writer(self.topics[endpoints.TWIST_ESTIMATE], TwistStamped,
                                               qos=pub(endpoints.TWIST_ESTIMATE))
        self.markers_writer = participant.writer(self.topics[endpoints.MARKERS], MarkerArray,
                                                 qos=pub(endpoints.MARKERS))
        self.joint_states_writer = participant.writer(self.topics[endpoints.MECHANISM_JOINT_STATES], JointState,
                                                      qos=pub(endpoints.MECHANISM_JOINT_STATES))
        self._encode = cdr.Encoder()
        self._raw_pose = cdr.RawWriter(self.pose_writer)
        self._raw_extras = {name: cdr.RawWriter(w).write for name, w in (
            ("tf", self.tf_writer), ("covariance", self.cov_writer), ("twist", self.twist_writer),
            ("markers", self.markers_writer), ("joint_states", self.joint_states_writer))}
        self.diag_writer = participant.writer(self.topics[endpoints.DIAGNOSTICS], DiagnosticArray,
                                              qos=pub(endpoints.DIAGNOSTICS))
        self._raw_diag = cdr.RawWriter(self.diag_writer)
        # latched (by default: transient-local, keep-last 1): a late subscriber gets the last answer
        self.modes_writer = participant.writer(self.topics[endpoints.ASSEMBLY_MODES], PoseArray,
                                               qos=pub(endpoints.ASSEMBLY_MODES))
        self.input_reader = participant.reader(self.topics[self.input_name],
                                               JointState if self.joint_state else Float64MultiArray,
                                               qos=sub(self.input_name))
        self.request_reader = participant.reader(self.topics[endpoints.REQUEST_ASSEMBLY_MODES], Empty,
                                                 qos=sub(endpoints.REQUEST_ASSEMBLY_MODES))
        self._extra_writers = (("tf", self.tf_writer), ("covariance", self.cov_writer),
                               ("twist", self.twist_writer), ("markers", self.markers_writer),
                               ("joint_states", self.joint_states_writer))
        self.loop, self.modes, self.reports = node_loops(
            service, publish_pose=self._publish_pose, publish_extras=self._publish_extras,
            subscribed=self._subscribed, publish_modes=self._publish_modes, publish_report=self._publish_report,
            modes_solve=modes_solve)
        self._stop = threading.Event()
        self._waitset, self._guard = endpoints.reader_waitset(participant, [self.input_reader, self.request_reader])
        self._lead = threading.Lock()           # held by the thread that waits for input
        self._reader_threads = [threading.Thread(target=self._read_loop, name=f"glpma_fk-reader-{i}", daemon=True)
                                for i in range(READER_THREADS)]

    def qos_of(self, entity: str):
        """``name -> QosSpec`` of this node's ``entity`` (publisher or subscription) endpoints."""
        return lambda name: self.qos[(name, entity)]

    def start(self) -> "DdsNode":
        self.modes.start()
        self.reports.start()
        for thread in self._reader_threads:
            thread.start()
        return self

    # -- data path -------------------------------------------------------------------------
    def _read_loop(self) -> None:
        while not self._stop.is_set():
            with self._lead:
                if self._stop.is_set():
                    return
                self._waitset.wait(duration(milliseconds=200))
                taken = self._take_input()
                self._take_requests()
            if taken is not None:
                self._offer(*taken)

    def _take_input(self):
        """The newest input taken, as ``(bytes, arrival_ns, arrival)``, or None; the others taken with it
        count as dropped."""
        try:
            samples = cdr.take_raw(self.input_reader, TAKE_BATCH)
        except Exception as exc:  # noqa: BLE001
            self.service.log.warning(f"could not take {self.input_name}: {exc}")
            return None
        arrival, arrival_ns = time.perf_counter(), time.time_ns()
        valid = [data for data, info in samples if info.valid_data]
        if not valid:
            return None
        if len(valid) > 1:
            self.service.note_dropped(len(valid) - 1)
        return valid[-1], arrival_ns, arrival

    def _offer(self, data: bytes, arrival_ns: int, arrival: float) -> None:
        """An input taken, to the solve loop: a leg_lengths message in one compiled call where that applies,
        else decoded (a sample that does not deserialize: one warning)."""
        if not self.joint_state and self.loop.offer_message(data, arrival_ns, arrival):
            return
        try:
            decoded = self._decode(data, arrival_ns)
        except Exception as exc:  # noqa: BLE001 - a sample that does not deserialize
            self.service.log.warning(f"could not read {self.input_name}: {exc}")
            return
        self.loop.offer(*decoded, arrival)

    def _decode(self, data: bytes, arrival_ns: int) -> tuple:
        fast = cdr.little_endian_cdr(data)
        if self.joint_state:
            if fast:
                stamp_ns, names, positions, velocities = cdr.joint_state_fields(data)
            else:
                msg = JointState.deserialize(data)
                stamp_ns, names, positions, velocities = (msg.header.stamp.to_ns(), tuple(msg.name),
                                                          tuple(msg.position), tuple(msg.velocity))
            return JointStateInput(names, positions, velocities), stamp_ns
        return (cdr.float64_multi_array_data(data) if fast else tuple(Float64MultiArray.deserialize(data).data),
                arrival_ns)

    def _take_requests(self) -> None:
        try:
            requests = [s for s in self.request_reader.take(TAKE_BATCH) if isinstance(s, Empty)]
        except Exception as exc:  # noqa: BLE001
            self.service.log.warning(f"could not take request_assembly_modes: {exc}")
            return
        if requests:
            if len(requests) > 1:
                self.service.modes.note(coalesced=len(requests) - 1)
            self.modes.request(time.time_ns())

    def _publish_pose(self, pose) -> None:
        self._raw_pose.write(self._encode.pose(pose))

    def _subscribed(self) -> set:
        """The extra outputs some reader is matched with (the others are not built)."""
        return {name for name, writer in self._extra_writers if writer.get_matched_subscriptions()}

    def _publish_extras(self, ex) -> None:
        """/tf, pose_estimate_cov, twist_estimate, ~/markers, ~/mechanism_joint_states of
        :class:`~glpma_ros.node.outputs.ExtraOutputs`."""
        for name, data in self._encode.extras(ex):
            self._raw_extras[name](data)

    def _publish_modes(self, modes) -> None:
        self.modes_writer.write(pose_array_message(modes))

    def _publish_report(self, report) -> None:
        """Encoded by :func:`cdr.diagnostic_array <glpma_ros.node.dds.cdr.diagnostic_array>` in chunks, with the
        report thread's pauses between them (the binding's serializer would hold the interpreter's lock for the
        whole report in one piece)."""
        self._raw_diag.write(cdr.diagnostic_array(time.time_ns(), report, pause=pause_report))

    def publish_diagnostics(self) -> None:
        """Publish a report now (the report thread does every ``diagnostics_period_s``)."""
        self._publish_report(self.service.diagnostics())

    # -- lifecycle -----------------------------------------------------------------------------
    def spin(self, stop: threading.Event, reload=None) -> None:
        """Wait until ``stop`` is set; call ``reload()`` when ``reload.requested`` (set by SIGHUP)."""
        while not stop.wait(RELOAD_POLL_S):
            if reload is not None and reload.requested.is_set():
                reload.requested.clear()
                reload()

    def close(self) -> None:
        self._stop.set()
        self._guard.set(True)
        for thread in self._reader_threads:
            thread.join(2.0)
        self.loop.stop()
        self.modes.stop()
        self.reports.stop()


def node_qos(service: FkService, remaps: dict, qos_overrides: dict) -> tuple[dict, list]:
    """Every endpoint's QoS (:func:`glpma_ros.node.qos.resolve`) for the service's ``qos_depth``,
    input topic and node name, the topics remapped by ``remaps``; :class:`InputError` for a bad value."""
    input_name = service.input_topic
    return qos.resolve(qos_overrides, service.params["qos_depth"], input_name, service.node_name,
                       topic_of=lambda name: remapped(name, remaps))


class ParameterReload:
    """SIGHUP: re-read the ``--ros-args`` (params files included) and apply what changed."""

    def __init__(self, service: FkService, argv):
        self.service = service
        self.argv = list(argv)
        self.requested = threading.Event()

    def __call__(self) -> None:
        log = self.service.log
        try:
            values, _, _ = node_values(self.argv)
        except InputError as exc:
            log.error(f"parameter reload failed, keeping the current values: {exc}")
            return
        changed = {k: v for k, v in values.items() if v != self.service.params[k]}
        if not changed:
            log.info("parameter reload: nothing changed")
        for name, value in changed.items():
            ok, reason = self.service.set_parameters({name: value})
            if not ok:
                log.error(f"parameter reload: {reason}; keeping {name}={self.service.params[name]!r}")


def _error(message: str, code: int = 2) -> int:
    print(f"glpma_fk: error: {message}", file=sys.stderr)
    return code


def main(argv=None) -> int:
    """Run the node over Cyclone DDS until SIGINT/SIGTERM; returns the exit status
    (2 for bad parameters or configuration, 1 for a DDS failure)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    transport, argv = split_transport(argv, default="dds")
    if transport not in ("dds", "auto"):
        return _error(f"this is the Cyclone DDS transport; --transport {transport} is not it")
    try:
        check_dds_transport()
        ros = parse_ros_args(argv)
    except InputError as exc:
        return _error(str(exc))
    if ros.other:
        return _error(f"unexpected arguments {' '.join(ros.other)!r} (parameters go after --ros-args)")
    logging.addLevelName(logging.WARNING, "WARN")     # ROS 2's spelling
    logging.basicConfig(level=(ros.log_level or "info").upper(), format=LOG_FORMAT, stream=sys.stderr)
    log = logging.getLogger(ros.node_name)
    for warning in ros.warnings:
        log.warning(warning)
    try:
        values, warnings = P.resolve(ros.overrides)
        for warning in warnings:
            log.warning(warning)
        service = FkService(values, logger=log, node_name=ros.node_name)
        node_qos(service, ros.remaps, ros.overrides)        # a bad QoS override: refused before the warm-up
        domain_id = endpoints.domain_id_from_env()
    except (GlpmaError, ValueError) as exc:
        return _error(str(exc))

    log.info(f"{service.describe()}; warming up the solvers (Numba compiles on first use)")
    log.info(f"warm-up done in {service.warm_up():.2f} s")
    try:
        node = DdsNode(service, endpoints.Participant(domain_id), ros.remaps, qos_overrides=ros.overrides).start()
    except Exception as exc:  # noqa: BLE001 - e.g. a bad CYCLONEDDS_URI
        return _error(f"cannot start Cyclone DDS: {exc}", 1)

    stop = threading.Event()
    reload = ParameterReload(service, argv)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    if hasattr(signal, "SIGHUP"):
        signal.signal(signal.SIGHUP, lambda *_: reload.requested.set())
    topics = ", ".join(f"rt/{t.lstrip('/')}" for t in node.topics.values())
    print(f"[{ros.node_name}] ready: domain {domain_id}, topics {topics}", flush=True)
    try:
        node.spin(stop, reload)
    finally:
        node.close()
        log.info(f"stopped: {service.summary()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
