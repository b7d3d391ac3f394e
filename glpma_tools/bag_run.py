"""One ``glpma-fk bag`` run (:mod:`glpma_tools.bag`): read the input bag, solve every input
with the node's :class:`~glpma_ros.node.service.FkService`, write the output bag.

:func:`open_bag` opens the input read-only; :class:`BagRun` checks the topics, copies
every connection, adds the pose / ``/tf`` / status connections, runs the loop and moves
the staged output into place (what it reports: :mod:`glpma_tools.bag_outcome`); :class:`BagJob` and
:func:`process_bag` make a run a task of the engines (one or several input bags).
"""
from __future__ import annotations

import logging
import shutil
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from glpma_ros.errors import InputError
from glpma_ros.estimation.estimator import STATUS_CONVERGED
from glpma_ros.node import params as P
from glpma_ros.node.dds import cdr
from glpma_ros.node.dds.rosbag import (
    FLOAT64_MULTI_ARRAY,
    JOINT_STATE,
    POSE_STAMPED,
    decode_float64_multi_array,
    decode_joint_state,
    open_bag,
)
from glpma_ros.node.diagnostics import ERROR, OK, WARN
from glpma_ros.node.service import FkService

from .bag_outcome import BranchWatch, Summary

#: the ROS 2 types the tool writes besides those it reads (glpma_ros.node.dds.rosbag)
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
DIAGNOSTIC_STATUS = "diagnostic_msgs/msg/DiagnosticStatus"
INPUT_MSGTYPES = {P.INPUT_FLOAT64_MULTI_ARRAY: FLOAT64_MULTI_ARRAY, P.INPUT_JOINT_STATE: JOINT_STATE}
#: statuses of inputs the estimator never saw
STATUS_INVALID, STATUS_UNDECODABLE, STATUS_INTERNAL = "invalid_input", "undecodable", "internal_error"
#: history depth of /tf, as tf2_ros' TransformBroadcaster offers it
TF_QOS_DEPTH = 100
#: RMW_DURATION_INFINITE as rosbag2 writes it in the QoS metadata (s, ns)
INFINITE_DURATION = (9223372036, 854775807)
#: messages between two progress-bar updates
PROGRESS_EVERY = 500
#: distinct status messages kept serialized (converged ones repeat; rejections rarely do)
STATUS_CACHE_SIZE = 1024


def _leg_values(est, service) -> tuple:
    """Redundant legs: the leg most likely at fault and the one left out of the pose, by joint name."""
    names = service.joint_names
    legs = (("suspect_leg", est.suspect_leg), ("excluded_leg", est.excluded_leg))
    return tuple((key, names[leg]) for key, leg in legs if leg is not None)


def topic_name(name: str, node_name: str, remaps: dict) -> str:
    """A topic name as ``ros2 bag record`` stores it: remapped like the node's (``-r FROM:=TO``),
    absolute, ``~/x`` in the node's namespace (``/glpma_fk/x``)."""
    name = remaps.get(name, remaps.get(name.lstrip("/"), remaps.get("/" + name.lstrip("/"), name)))
    if name.startswith("~"):
        return f"/{node_name}/{name[1:].lstrip('/')}"
    return "/" + name.lstrip("/")


def _qos(depth: int):
    # the bag extra: optional, imported where used
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
    infinite = QosTime(*INFINITE_DURATION)
    return Qos(QosHistory.KEEP_LAST, depth, QosReliability.RELIABLE, QosDurability.VOLATILE, infinite, infinite,
               QosLiveliness.AUTOMATIC, infinite, False)


def _storage_of(reader) -> str:
    from rosbags.rosbag2.storage_mcap import McapReader  # the bag extra: optional, imported where used
    storages = getattr(reader.storage, "storages", None) or [reader.storage]
    return "mcap" if isinstance(storages[0], McapReader) else "sqlite3"


class BagRun:
    """One run: an input bag, a service, an output bag."""

    def __init__(self, service, input_path: Path, output_path: Path, *, input_topic: str, pose_topic: str,
                 tf_topic: str | None, status_topic: str, child_frame_id: str, storage: str | None,
                 progress: bool, log):
        from rosbags.typesys import Stores, get_typestore  # the bag extra: optional, imported where used
        self.service, self.log = service, log
        self.model = service.model
        self.joint_state = service.input_type == P.INPUT_JOINT_STATE
        self.input_path, self.output_path = input_path, output_path
        self.topics = {"input": input_topic, "pose": pose_topic, "tf": tf_topic, "status": status_topic}
        self.child_frame_id, self.progress = child_frame_id, progress
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        self.reader = open_bag(input_path)
        try:
            self.storage = storage or _storage_of(self.reader)
            self._check_topics()
        except BaseException:
            self.reader.close()
            raise
        self.summary = Summary(str(input_path), str(output_path), self.storage, input_topic,
                               budget_ms=service.params["time_budget_ms"])
        self.status_name = f"{service.node_name}: forward kinematics"
        self.hardware_id = f"{self.model.kind}:{Path(str(getattr(self.model, 'source', ''))).name}"
        self._status_cache: dict = {}

    def _check_topics(self) -> None:
        outputs = [t for t in (self.topics["pose"], self.topics["tf"], self.topics["status"]) if t is not None]
        if len(set(outputs)) < len(outputs):
            raise InputError(f"the output topics must differ, got {', '.join(outputs)}")
        conns = self.reader.connections
        by_topic: dict = {}
        for c in conns:
            by_topic.setdefault(c.topic, set()).add(c.msgtype)
        want = INPUT_MSGTYPES[self.service.input_type]
        topic = self.topics["input"]
        if topic not in by_topic:
            listed = ", ".join(f"{t} ({'/'.join(sorted(ts))})" for t, ts in sorted(by_topic.items())) or "none"
            raise InputError(f"{self.input_path} has no topic {topic} (topics: {listed}); "
                             f"choose one with --legs-topic / --joint-states-topic")
        other = sorted(by_topic[topic] - {want})
        if other:
            hint = (" (JointState input: --joint-names or --input-type joint_state)" if JOINT_STATE in other
                    else " (Float64MultiArray input: --input-type float64_multi_array)"
                    if FLOAT64_MULTI_ARRAY in other else "")
            raise InputError(f"topic {topic} has type {', '.join(other)}, expected {want}{hint}")
        for key, option in (("pose", "--pose-topic"), ("status", "--status-topic")):
            if self.topics[key] in by_topic:
                raise InputError(f"{self.input_path} already has a topic {self.topics[key]}; "
                                 f"write the estimates elsewhere with {option}")
        tf = self.topics["tf"]
        if tf is not None and tf in by_topic and by_topic[tf] != {TF_MESSAGE}:
            raise InputError(f"topic {tf} has type {', '.join(sorted(by_topic[tf]))}, not {TF_MESSAGE}; "
                             f"use --tf-topic or --no-tf")

    # -- output connections ------------------------------------------------------------------------
    def _copy_connections(self, writer) -> dict:
        """Input connection id -> output connection, for every topic that can be copied."""
        from rosbags.interfaces import MessageDefinitionFormat  # the bag extra: optional, imported where used
        from rosbags.rosbag2 import WriterError
        out, made = {}, {}
        for c in self.reader.connections:
            key = (c.topic, c.msgtype, c.ext.serialization_format, tuple(c.ext.offered_qos_profiles))
            if key in made:
                out[c.id] = made[key]
                continue
            msgdef = c.msgdef.data if c.msgdef.format != MessageDefinitionFormat.NONE and c.msgdef.data else None
            digest = c.digest or None
            kwargs = {"msgdef": msgdef, "rihs01": digest}
            if msgdef is None or digest is None:
                if c.msgtype not in self.typestore.types:
                    self.summary.skipped_topics[c.topic] = (f"type {c.msgtype} has no definition in the bag and is "
                                                            f"not a ROS 2 Jazzy type")
                    continue
                kwargs = {"typestore": self.typestore}
            try:
                made[key] = out[c.id] = writer.add_connection(
                    c.topic, c.msgtype, serialization_format=c.ext.serialization_format,
                    offered_qos_profiles=c.ext.offered_qos_profiles, **kwargs)
            except WriterError as exc:
                self.summary.skipped_topics[c.topic] = str(exc)
        return out

    def _output_connections(self, writer, copied: dict):
        depth = self.service.params["qos_depth"]
        pose = writer.add_connection(self.topics["pose"], POSE_STAMPED, typestore=self.typestore,
                                     offered_qos_profiles=[_qos(depth)])
        status = writer.add_connection(self.topics["status"], DIAGNOSTIC_STATUS, typestore=self.typestore,
                                       offered_qos_profiles=[_qos(depth)])
        tf = None
        if self.topics["tf"] is not None:
            tf = next((copied[c.id] for c in self.reader.connections
                       if c.topic == self.topics["tf"] and c.id in copied), None)
            if tf is None:
                tf = writer.add_connection(self.topics["tf"], TF_MESSAGE, typestore=self.typestore,
                                           offered_qos_profiles=[_qos(TF_QOS_DEPTH)])
        return pose, tf, status

    def _status(self, level: int, message: str, values: tuple) -> bytes:
        key = (level, message, values)
        raw = self._status_cache.get(key)
        if raw is None:
            T = self.typestore.types
            msg = T[DIAGNOSTIC_STATUS](level=level, name=self.status_name, message=message,
                                       hardware_id=self.hardware_id,
                                       values=[T["diagnostic_msgs/msg/KeyValue"](key=k, value=v) for k, v in values])
            raw = bytes(self.typestore.serialize_cdr(msg, DIAGNOSTIC_STATUS))
            if len(self._status_cache) < STATUS_CACHE_SIZE:
                self._status_cache[key] = raw
        return raw

    # -- the loop --------------------------------------------------------------------------------------
    def run(self) -> Summary:
        from rosbags.rosbag2 import StoragePlugin, Writer  # the bag extra: optional, imported where used
        from tqdm import tqdm  # the tools extra: optional, imported where used
        parent = self.output_path.parent
        parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{self.output_path.name}.", dir=parent))
        try:
            writer = Writer(staging / self.output_path.name, version=9,
                            storage_plugin=StoragePlugin.MCAP if self.storage == "mcap" else StoragePlugin.SQLITE3)
            mode = self.reader.compression_mode
            if mode in ("file", "message"):
                # the bag extra: optional, imported where used
                from rosbags.rosbag2 import CompressionFormat, CompressionMode
                writer.set_compression(CompressionMode[mode.upper()], CompressionFormat.ZSTD)
            writer.open()
            copied = self._copy_connections(writer)
            outputs = self._output_connections(writer, copied)
            self.summary.warm_up_s = self.service.warm_up(solvers=(self.service.params["solver"],))
            t1, c1 = time.perf_counter(), time.process_time()
            with tqdm(total=self.reader.message_count, unit="msg", disable=None if self.progress else True,
                      file=sys.stderr, dynamic_ncols=True, desc="bag") as bar:
                self._loop(writer, copied, outputs, bar)
            writer.close()
            self.summary.elapsed_s = time.perf_counter() - t1
            self.summary.cpu_s = time.process_time() - c1
            if self.output_path.exists() or self.output_path.is_symlink():
                if self.output_path.is_dir() and not self.output_path.is_symlink():
                    shutil.rmtree(self.output_path)
                else:
                    self.output_path.unlink()
            (staging / self.output_path.name).rename(self.output_path)
        finally:
            self.reader.close()
            shutil.rmtree(staging, ignore_errors=True)
        return self.summary

    def _loop(self, writer, copied: dict, outputs, bar) -> None:
        pose_conn, tf_conn, status_conn = outputs
        service, ts, summary = self.service, self.typestore, self.summary
        frame_id = service.frame_id
        encode = cdr.Encoder()          # the node's: PoseStamped and TFMessage as rmw_cyclonedds_cpp writes them
        child_frame_id = self.child_frame_id
        input_ids = {c.id for c in self.reader.connections if c.topic == self.topics["input"]}
        estimator = service.estimator
        watch = BranchWatch(self.model, estimator.last_x, estimator.last_legs)
        undecodable: Counter = Counter()
        write = writer.write
        count = 0
        for conn, t_log, raw in self.reader.messages():
            count += 1
            if count % PROGRESS_EVERY == 0:
                bar.update(PROGRESS_EVERY)
            out = copied.get(conn.id)
            if out is not None:
                write(out, t_log, raw)
            if conn.id not in input_ids:
                continue
            summary.inputs += 1
            t = time.perf_counter()
            try:
                if self.joint_state:
                    names, positions, stamp_ns = decode_joint_state(raw, ts)
                else:
                    legs_m, stamp_ns = decode_float64_multi_array(raw, ts), t_log
            except Exception as exc:  # noqa: BLE001 - any malformed message is skipped with its reason
                reason = f"cannot decode {conn.msgtype}: {type(exc).__name__}"
                undecodable[reason] += 1
                write(status_conn, t_log, self._status(ERROR, f"{reason}: {exc}"[:200],
                                                       (("status", STATUS_UNDECODABLE),)))
                continue
            if self.joint_state:
                outcome = service.handle_joint_state(names, positions, stamp_ns)
            else:
                outcome = service.handle(legs_m, stamp_ns)
            summary.solve_s += time.perf_counter() - t
            est = outcome.estimate
            if outcome.pose is not None:
                summary.converged += 1
                p = outcome.pose
                write(pose_conn, t_log, encode.pose_stamped(p.stamp_ns, frame_id, p.position, p.orientation))
                if tf_conn is not None:
                    write(tf_conn, t_log, encode.tf_message(p.stamp_ns, frame_id, child_frame_id, p.position,
                                                            p.orientation))
                status = (("status", est.status), ("start", est.start)) + _leg_values(est, service)
                if watch(est.x, service.estimator.last_legs):
                    summary.mode_changes += 1
                    status += (("assembly_mode_change", "true"),)
                if est.converged:
                    write(status_conn, t_log, self._status(OK, STATUS_CONVERGED, status))
                else:       # inconsistent legs, the faulty one left out of the pose
                    write(status_conn, t_log, self._status(WARN, est.message, status))
            elif est is not None:
                write(status_conn, t_log, self._status(WARN, outcome.reason, (("status", est.status),
                                                                              ("start", est.start))
                                                       + _leg_values(est, service)))
            else:
                key = STATUS_INTERNAL if outcome.reason.startswith("internal error") else STATUS_INVALID
                write(status_conn, t_log, self._status(ERROR, outcome.reason, (("status", key),)))
        bar.update(count % PROGRESS_EVERY)
        summary.messages = count
        summary.rejected = Counter(service.stats.reasons) + undecodable


# -- one bag as a task (glpma-fk bag, one or several inputs) -----------------------------------------

class _TqdmHandler(logging.Handler):
    """Log lines that do not break the progress bar."""

    def emit(self, record):
        from tqdm import tqdm  # the tools extra: optional, imported where used
        tqdm.write(self.format(record), file=sys.stderr)


def make_logger(node_name: str, level: int) -> logging.Logger:
    """The run's logger: ``[LEVEL] [node.bag]: message`` on stderr, above a progress bar."""
    log = logging.getLogger(f"{node_name}.bag")
    log.propagate = False
    handler = _TqdmHandler()
    handler.setFormatter(logging.Formatter("[%(levelname)s] [%(name)s]: %(message)s"))
    log.handlers[:] = [handler]
    log.setLevel(level)
    return log


@dataclass(frozen=True)
class BagJob:
    """Everything a run needs besides its input and output paths (picklable: a worker process or a
    Dask worker gets it once): the node's resolved parameters, the resolved topic names."""

    values: dict
    node_name: str
    input_topic: str
    pose_topic: str
    tf_topic: str | None
    status_topic: str
    child_frame_id: str
    storage: str | None
    log_level: int = logging.WARNING

    def service(self, log):
        try:
            return FkService(self.values, logger=log, node_name=self.node_name)
        except ValueError as exc:
            raise InputError(str(exc)) from None


def process_bag(job: BagJob, input_path: str, output_path: str, progress: bool = False, service=None) -> Summary:
    """One bag with a service of its own (the warm start begins afresh with every bag): what
    ``glpma-fk bag`` runs for each input, in this process or on a worker."""
    log = make_logger(job.node_name, job.log_level)
    service = job.service(log) if service is None else service
    bag = BagRun(service, Path(input_path), Path(output_path), input_topic=job.input_topic,
                 pose_topic=job.pose_topic, tf_topic=job.tf_topic, status_topic=job.status_topic,
                 child_frame_id=job.child_frame_id, storage=job.storage, progress=progress, log=log)
    return bag.run()
