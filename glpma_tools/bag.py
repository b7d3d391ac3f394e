"""``glpma-fk bag INPUT OUTPUT``: the node's poses for a recorded rosbag2, offline.

The input bag (MCAP or SQLite3 storage, read with the pure-Python ``rosbags``
library, opened read-only) is read in its order (log time, i.e. the order in which
the recorder received the messages); every message of the input topic --
``leg_lengths`` (std_msgs/msg/Float64MultiArray) or ``joint_states``
(sensor_msgs/msg/JointState) -- goes through the node's own
:class:`~glpma_ros.node.service.FkService`: the same parameters (``--ros-args -p
NAME:=VALUE --params-file FILE``, parsed by :mod:`glpma_ros.node.params`), the same unit
conversion, validation, joint picking, estimator and warm start, carried from one
input to the next through the whole bag.  The output bag holds every input message
byte for byte (all topics, same types, definitions and QoS metadata) and, for each
input, logged at the input's log time:

* ``pose_estimate`` (geometry_msgs/msg/PoseStamped) when the input converged, stamped
  as the node stamps it: the input's receive time (its log time in the bag) for a
  Float64MultiArray, the header.stamp of a JointState;
* ``/tf`` (tf2_msgs/msg/TFMessage): the same pose as the transform frame_id -> child
  frame (default ``platform``); appended to the bag's own ``/tf`` when it has one;
* ``~/status`` (diagnostic_msgs/msg/DiagnosticStatus, ``/glpma_fk/status`` for the node
  name ``glpma_fk``): what became of the input -- level OK / WARN / ERROR, message
  ``converged`` or the reason of the rejection, values ``status`` (converged,
  no_solution, near_singular, budget_exhausted, invalid_input, undecodable,
  internal_error), ``start`` (warm, widened, cold) and ``assembly_mode_change``.

The node's time budget (``time_budget_ms``, 2 ms) is a real-time deadline; offline it
is ``--budget-ms``, by default the largest value the parameter takes
(``OFFLINE_BUDGET_MS``), so that every status is decided by the work done -- also
when the node's params file sets a real-time budget.

A message that cannot be decoded is copied, counted and reported with its reason;
nothing aborts the run but an unreadable bag.  The output is written next to OUTPUT
and moved into place at the end: an interrupted run leaves no partial bag.
"""
from __future__ import annotations

import argparse
import json
import logging
import math
import shutil
import struct
import sys
import textwrap
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from glpma_ros.node import params as P
from glpma_ros.node.ros_args import ROS_ARGS_HELP, parse_ros_args
from glpma_ros.cli import OneLineParser
from glpma_ros.errors import GlpmaError, InputError
from glpma_ros.estimator import CONTINUITY_FACTOR, MIN_SPREAD, STATUS_CONVERGED
from glpma_ros.node.diagnostics import ERROR, OK, WARN

from .extras import require

PROG = "glpma-fk bag"
FLOAT64_MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
JOINT_STATE = "sensor_msgs/msg/JointState"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
DIAGNOSTIC_STATUS = "diagnostic_msgs/msg/DiagnosticStatus"
INPUT_MSGTYPES = {P.INPUT_FLOAT64_MULTI_ARRAY: FLOAT64_MULTI_ARRAY, P.INPUT_JOINT_STATE: JOINT_STATE}
STORAGES = ("mcap", "sqlite3")

#: offline time budget per input: the largest the parameter accepts (ms)
OFFLINE_BUDGET_MS = P.SPECS["time_budget_ms"].range[1]
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
NS_PER_S = 1_000_000_000
#: width of the --help texts
HELP_WIDTH = 100
#: CDR little-endian encapsulation header (rosbag2 and every ROS 2 rmw write it)
CDR_LE = b"\x00\x01\x00\x00"
_STAMP = struct.Struct("<iI")
_POSE = struct.Struct("<7d")
_UINT32 = struct.Struct("<I")


# -- encoding and decoding ------------------------------------------------------------------------

class StampedPoseCodec:
    """CDR of a message that is a stamp, fixed strings and the seven doubles of a pose
    (position x y z, quaternion x y z w) -- PoseStamped, or a TFMessage with one transform.

    ``rosbags`` serializes a probe message once; the stamp and the seven doubles are
    located in it by their (unique) probe values, and every later message is the probe's
    bytes with these two fields packed in, checked against ``rosbags`` on a second sample.
    Should the check fail, every message is serialized by ``rosbags`` instead."""

    PROBE_STAMP = (0x1A2B3C4D, 0x0A1B2C3D)
    PROBE_VALUES = (1.5, -2.25, 3.125, 0.0625, -0.125, 0.25, -0.5)
    CHECK_STAMP_NS = 1_700_000_123_456_789_012
    CHECK_VALUES = (0.1, -0.2, 0.3, 0.0, 0.0, math.sin(0.35), math.cos(0.35))

    def __init__(self, typestore, msgtype: str, build):
        """``build(sec, nanosec, values)``: the rosbags message."""
        self.typestore, self.msgtype, self.build = typestore, msgtype, build
        self.fast = False
        raw = self._serialize(*self.PROBE_STAMP, self.PROBE_VALUES)
        stamp, values = _STAMP.pack(*self.PROBE_STAMP), _POSE.pack(*self.PROBE_VALUES)
        i, j = raw.find(stamp), raw.find(values)
        if raw[:4] == CDR_LE and 0 <= i and i + len(stamp) <= j and raw.count(stamp) == raw.count(values) == 1:
            self.head, self.middle, self.tail = raw[:i], raw[i + len(stamp):j], raw[j + len(values):]
            self.fast = True
            check = self.encode(self.CHECK_STAMP_NS, self.CHECK_VALUES)
            self.fast = check == self._serialize(*divmod(self.CHECK_STAMP_NS, NS_PER_S), self.CHECK_VALUES)

    def _serialize(self, sec, nanosec, values) -> bytes:
        return bytes(self.typestore.serialize_cdr(self.build(sec, nanosec, values), self.msgtype))

    def encode(self, stamp_ns: int, values) -> bytes:
        sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
        if not self.fast:
            return self._serialize(sec, nanosec, values)
        return b"".join((self.head, _STAMP.pack(sec, nanosec), self.middle, _POSE.pack(*values), self.tail))


def pose_stamped_codec(typestore, frame_id: str) -> StampedPoseCodec:
    T = typestore.types

    def build(sec, nanosec, v):
        header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                          frame_id=frame_id)
        pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=v[0], y=v[1], z=v[2]),
                                           orientation=T["geometry_msgs/msg/Quaternion"](x=v[3], y=v[4], z=v[5],
                                                                                         w=v[6]))
        return T[POSE_STAMPED](header=header, pose=pose)
    return StampedPoseCodec(typestore, POSE_STAMPED, build)


def tf_codec(typestore, frame_id: str, child_frame_id: str) -> StampedPoseCodec:
    T = typestore.types

    def build(sec, nanosec, v):
        header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                          frame_id=frame_id)
        transform = T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=v[0], y=v[1], z=v[2]),
            rotation=T["geometry_msgs/msg/Quaternion"](x=v[3], y=v[4], z=v[5], w=v[6]))
        stamped = T["geometry_msgs/msg/TransformStamped"](header=header, child_frame_id=child_frame_id,
                                                           transform=transform)
        return T[TF_MESSAGE](transforms=[stamped])
    return StampedPoseCodec(typestore, TF_MESSAGE, build)


def decode_float64_multi_array(raw, typestore) -> np.ndarray:
    """``data`` of a std_msgs/msg/Float64MultiArray.  The usual message (little-endian, no
    layout dimensions, data_offset 0) is read in place; anything else by ``rosbags``."""
    if len(raw) >= 20 and raw[:4] == CDR_LE and not any(raw[4:12]):
        n = _UINT32.unpack_from(raw, 12)[0]          # data length; the doubles start 8-aligned at 20
        if len(raw) == 20 + 8 * n:
            return np.frombuffer(raw, dtype="<f8", count=n, offset=20)
    return np.asarray(typestore.deserialize_cdr(raw, FLOAT64_MULTI_ARRAY).data, dtype=float)


def decode_joint_state(raw, typestore):
    """``(names, positions, header.stamp in ns)`` of a sensor_msgs/msg/JointState."""
    msg = typestore.deserialize_cdr(raw, JOINT_STATE)
    stamp = msg.header.stamp
    return list(msg.name), np.asarray(msg.position, dtype=float), stamp.sec * NS_PER_S + stamp.nanosec


# -- the run ----------------------------------------------------------------------------------------

@dataclass
class Summary:
    """What a run did."""

    input: str
    output: str
    storage: str
    input_topic: str
    messages: int = 0                  # messages read (all topics)
    inputs: int = 0                    # messages of the input topic
    converged: int = 0                 # poses written
    rejected: Counter = field(default_factory=Counter)   # reason -> inputs
    mode_changes: int = 0
    skipped_topics: dict = field(default_factory=dict)   # topic -> why it could not be copied
    budget_ms: float = 0.0             # time budget per input
    warm_up_s: float = 0.0
    elapsed_s: float = 0.0             # reading, solving and writing (after the warm-up)
    cpu_s: float = 0.0                 # this process' CPU time meanwhile (a shared machine's wall clock runs ahead)
    solve_s: float = 0.0               # in the service alone

    @property
    def poses_per_s(self) -> float:
        return self.converged / self.elapsed_s if self.elapsed_s > 0 else 0.0

    def as_dict(self) -> dict:
        return {"input": self.input, "output": self.output, "storage": self.storage,
                "input_topic": self.input_topic, "messages": self.messages, "inputs": self.inputs,
                "converged": self.converged, "rejected": sum(self.rejected.values()),
                "rejected_by_reason": dict(self.rejected.most_common()), "assembly_mode_changes": self.mode_changes,
                "skipped_topics": self.skipped_topics, "budget_ms": self.budget_ms, "warm_up_s": self.warm_up_s,
                "elapsed_s": self.elapsed_s, "cpu_s": self.cpu_s, "solve_s": self.solve_s,
                "poses_per_s": self.poses_per_s}

    def text(self) -> str:
        lines = [f"{self.output} ({self.storage}): {self.messages} messages copied, {self.inputs} inputs on "
                 f"{self.input_topic}: {self.converged} converged, {sum(self.rejected.values())} rejected, "
                 f"{self.mode_changes} assembly-mode changes",
                 f"  {self.elapsed_s:.2f} s, CPU {self.cpu_s:.2f} s ({self.poses_per_s:,.0f} poses/s; solving "
                 f"{self.solve_s:.2f} s, "
                 f"warm-up {self.warm_up_s:.1f} s before; budget {self.budget_ms:g} ms per input)"]
        lines += [f"  rejected {n}: {reason}" for reason, n in self.rejected.most_common()]
        lines += [f"  not copied: {topic}: {why}" for topic, why in self.skipped_topics.items()]
        return "\n".join(lines)


class BranchWatch:
    """Counts assembly-mode changes: a converged pose farther from the previous one than
    the estimator's continuity bound (``CONTINUITY_FACTOR`` times the leg movement) jumped
    to another branch instead of following the legs."""

    def __init__(self, model, x=None, legs=None):
        self.model = model
        self.x, self.legs = x, legs

    def __call__(self, x, legs) -> bool:
        jumped = False
        if self.x is not None:
            movement = float(np.max(np.abs(legs - self.legs)))
            bound = max(CONTINUITY_FACTOR * movement, MIN_SPREAD * self.model.scale)
            jumped = self.model.distance(x, self.x) > bound
        self.x, self.legs = np.array(x, dtype=float), np.array(legs, dtype=float)
        return jumped


def topic_name(name: str, node_name: str, remaps: dict) -> str:
    """A topic name as ``ros2 bag record`` stores it: remapped like the node's (``-r FROM:=TO``),
    absolute, ``~/x`` in the node's namespace (``/glpma_fk/x``)."""
    name = remaps.get(name, remaps.get(name.lstrip("/"), remaps.get("/" + name.lstrip("/"), name)))
    if name.startswith("~"):
        return f"/{node_name}/{name[1:].lstrip('/')}"
    return "/" + name.lstrip("/")


def _qos(depth: int):
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
    infinite = QosTime(*INFINITE_DURATION)
    return Qos(QosHistory.KEEP_LAST, depth, QosReliability.RELIABLE, QosDurability.VOLATILE, infinite, infinite,
               QosLiveliness.AUTOMATIC, infinite, False)


def _storage_of(reader) -> str:
    from rosbags.rosbag2.storage_mcap import McapReader
    storages = getattr(reader.storage, "storages", None) or [reader.storage]
    return "mcap" if isinstance(storages[0], McapReader) else "sqlite3"


def open_bag(path: Path):
    """An open rosbags Reader (read-only), or :class:`InputError`."""
    from rosbags.rosbag2 import Reader
    if not path.exists():
        raise InputError(f"input bag {path} does not exist")
    try:
        reader = Reader(path)
        reader.open()
    except Exception as exc:  # noqa: BLE001 - ReaderError, OSError, or a malformed file
        raise InputError(f"cannot read bag {path}: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
                         ) from None
    return reader


class BagRun:
    """One run: an input bag, a service, an output bag."""

    def __init__(self, service, input_path: Path, output_path: Path, *, input_topic: str, pose_topic: str,
                 tf_topic: str | None, status_topic: str, child_frame_id: str, storage: str | None,
                 progress: bool, log):
        from rosbags.typesys import Stores, get_typestore
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
        from rosbags.interfaces import MessageDefinitionFormat
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
        from rosbags.rosbag2 import StoragePlugin, Writer
        from tqdm import tqdm
        parent = self.output_path.parent
        parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{self.output_path.name}.", dir=parent))
        try:
            writer = Writer(staging / self.output_path.name, version=9,
                            storage_plugin=StoragePlugin.MCAP if self.storage == "mcap" else StoragePlugin.SQLITE3)
            mode = self.reader.compression_mode
            if mode in ("file", "message"):
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
        pose_codec = pose_stamped_codec(ts, frame_id)
        tf_codec_ = tf_codec(ts, frame_id, self.child_frame_id) if tf_conn is not None else None
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
                values = (*p.position, *p.orientation)
                write(pose_conn, t_log, pose_codec.encode(p.stamp_ns, values))
                if tf_conn is not None:
                    write(tf_conn, t_log, tf_codec_.encode(p.stamp_ns, values))
                status = (("status", STATUS_CONVERGED), ("start", est.start))
                if watch(est.x, service.estimator.last_legs):
                    summary.mode_changes += 1
                    status += (("assembly_mode_change", "true"),)
                write(status_conn, t_log, self._status(OK, STATUS_CONVERGED, status))
            elif est is not None:
                write(status_conn, t_log, self._status(WARN, outcome.reason,
                                                       (("status", est.status), ("start", est.start))))
            else:
                key = STATUS_INTERNAL if outcome.reason.startswith("internal error") else STATUS_INVALID
                write(status_conn, t_log, self._status(ERROR, outcome.reason, (("status", key),)))
        bar.update(count % PROGRESS_EVERY)
        summary.messages = count
        summary.rejected = Counter(service.stats.reasons) + undecodable


# -- command line -----------------------------------------------------------------------------------

def _parameter_help() -> str:
    lines = ["ROS arguments:", *ROS_ARGS_HELP, "",
             "node parameters (after --ros-args: -p NAME:=VALUE, --params-file FILE; as for glpma-fk node):"]
    for spec in P.PARAMETERS:
        lines.append(f"  {spec.name} (default {spec.default if spec.default != [] else '[]'})")
    lines.append(textwrap.fill("time_budget_ms is replaced by --budget-ms; qos_depth sets the depth offered by the "
                               "new topics; the other real-time parameters (deadline_ms, diagnostics_period_s, "
                               "assembly_modes_runs) have no effect here.", HELP_WIDTH))
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter,
        usage=f"{PROG} INPUT OUTPUT [options] [--ros-args -p NAME:=VALUE ... --params-file FILE]",
        description=textwrap.fill(
                    "Estimate the platform pose for every leg_lengths (std_msgs/msg/Float64MultiArray) or "
                    "joint_states (sensor_msgs/msg/JointState) message of a recorded rosbag2 (MCAP or SQLite3) "
                    "with the node's estimator and parameters, and write a new bag: every input message copied "
                    "unchanged, plus pose_estimate (geometry_msgs/msg/PoseStamped), /tf (tf2_msgs/msg/TFMessage) "
                    "and ~/status (diagnostic_msgs/msg/DiagnosticStatus) per input. Topics are in metres.",
                    HELP_WIDTH, break_on_hyphens=False),
        epilog=_parameter_help())
    p.add_argument("input", metavar="INPUT", help="rosbag2 directory (or a single .mcap / .db3 file); read only")
    p.add_argument("output", metavar="OUTPUT", help="rosbag2 directory to create")
    p.add_argument("--storage", choices=STORAGES, default=None, help="storage of OUTPUT (default: INPUT's)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing OUTPUT (refused by default)")
    p.add_argument("--budget-ms", type=float, default=None, metavar="MS",
                   help=f"time budget of one input (parameter time_budget_ms; default {OFFLINE_BUDGET_MS:g}, its "
                        f"maximum, so that statuses depend on the work done only; a time_budget_ms in the "
                        f"parameters is replaced)")
    p.add_argument("--input-type", choices=P.INPUT_TYPES, default=None,
                   help="input message type (default: parameter input_type, float64_multi_array)")
    p.add_argument("--legs-topic", default="leg_lengths", metavar="TOPIC",
                   help="Float64MultiArray input topic (default leg_lengths, i.e. /leg_lengths)")
    p.add_argument("--joint-states-topic", default="joint_states", metavar="TOPIC",
                   help="JointState input topic (default joint_states)")
    p.add_argument("--joint-names", nargs="+", default=None, metavar="NAME",
                   help="JointState input: the legs' joint names in leg order (parameter joint_names); "
                        "implies --input-type joint_state")
    p.add_argument("--pose-topic", default="pose_estimate", metavar="TOPIC",
                   help="output PoseStamped topic (default pose_estimate)")
    p.add_argument("--tf-topic", default="/tf", metavar="TOPIC",
                   help="output TFMessage topic (default /tf; a /tf already in INPUT gets the transforms added)")
    p.add_argument("--no-tf", action="store_true", help="write no transforms")
    p.add_argument("--child-frame-id", default="platform", metavar="FRAME",
                   help="child frame of the transforms (default platform; the parent is parameter frame_id)")
    p.add_argument("--status-topic", default="~/status", metavar="TOPIC",
                   help="per-input status (default ~/status, i.e. /glpma_fk/status)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (none either when stderr is not "
                                                               "a terminal)")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    return p


class _TqdmHandler(logging.Handler):
    """Log lines that do not break the progress bar."""

    def emit(self, record):
        from tqdm import tqdm
        tqdm.write(self.format(record), file=sys.stderr)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        require("bag", PROG)
        ros = parse_ros_args(argv)
        args = build_parser().parse_args(ros.other)
        return run(args, ros)
    except GlpmaError as exc:
        print(f"error: {PROG}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


def run(args, ros) -> int:
    input_path, output_path = Path(args.input), Path(args.output)
    src, dst = input_path.resolve(), output_path.resolve()
    if dst == src or src.is_relative_to(dst) or dst.is_relative_to(src):
        raise InputError(f"OUTPUT {output_path} must be outside INPUT {input_path}")
    if (output_path.exists() or output_path.is_symlink()) and not args.overwrite:
        raise InputError(f"{output_path} exists (--overwrite replaces it)")
    if not args.child_frame_id.strip():
        raise InputError("--child-frame-id must not be empty")
    overrides = dict(ros.overrides)
    budget = OFFLINE_BUDGET_MS if args.budget_ms is None else args.budget_ms
    replaced = overrides.get("time_budget_ms")
    overrides["time_budget_ms"] = budget
    if args.joint_names is not None:
        overrides["joint_names"] = args.joint_names
        overrides["input_type"] = P.INPUT_JOINT_STATE
    if args.input_type is not None:
        overrides["input_type"] = args.input_type
    values, warnings = P.resolve(overrides)

    log = logging.getLogger(f"{ros.node_name}.bag")
    log.propagate = False
    handler = _TqdmHandler()
    handler.setFormatter(logging.Formatter("[%(levelname)s] [%(name)s]: %(message)s"))
    log.handlers[:] = [handler]
    level = logging.getLevelName((ros.log_level or "warning").upper())
    log.setLevel(level if isinstance(level, int) else logging.WARNING)
    for warning in [*ros.warnings, *warnings]:
        log.warning(warning)
    if replaced is not None and replaced != budget:
        log.info(f"time_budget_ms:={replaced} of the parameters replaced by {budget:g} (--budget-ms)")

    from glpma_ros.node.service import FkService
    try:
        service = FkService(values, logger=log, node_name=ros.node_name)
    except (GlpmaError, ValueError) as exc:
        raise InputError(str(exc)) from None
    input_name = "joint_states" if service.input_type == P.INPUT_JOINT_STATE else "leg_lengths"
    input_topic = args.joint_states_topic if input_name == "joint_states" else args.legs_topic
    name = ros.node_name
    bag = BagRun(service, input_path, output_path,
                 input_topic=topic_name(input_topic, name, ros.remaps),
                 pose_topic=topic_name(args.pose_topic, name, ros.remaps),
                 tf_topic=None if args.no_tf else topic_name(args.tf_topic, name, ros.remaps),
                 status_topic=topic_name(args.status_topic, name, ros.remaps),
                 child_frame_id=args.child_frame_id, storage=args.storage, progress=not args.no_progress, log=log)
    summary = bag.run()
    print(json.dumps(summary.as_dict()) if args.json else summary.text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
