"""Topics, QoS and endpoints as a ROS 2 Jazzy node on ``rmw_cyclonedds_cpp`` has them.

ROS topic ``name`` travels as DDS topic ``rt/name`` (a private ``~/name`` of node
``glpma_fk`` as ``rt/glpma_fk/name``); each reader and writer carries
``typehash=<RIHS01 hash>;`` as USER_DATA.  QoS: reliable, keep-last (depth), volatile
-- the ROS default profile -- or transient-local for a latched topic (``~/assembly_modes``).
"""
from __future__ import annotations

import os
import time

from cyclonedds.core import GuardCondition, InstanceState, Policy, Qos, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from ..qos import TF_DEPTH, QosSpec  # noqa: F401 - TF_DEPTH: the depth of /tf, re-exported
from .messages import type_hash
from .security import check_dds_transport

LEG_LENGTHS = "leg_lengths"
JOINT_STATES = "joint_states"
POSE_ESTIMATE = "pose_estimate"
POSE_ESTIMATE_COV = "pose_estimate_cov"
TWIST_ESTIMATE = "twist_estimate"
TF = "/tf"
MARKERS = "~/markers"
MECHANISM_JOINT_STATES = "~/mechanism_joint_states"
DIAGNOSTICS = "/diagnostics"
ASSEMBLY_MODES = "~/assembly_modes"
REQUEST_ASSEMBLY_MODES = "~/request_assembly_modes"


def expand_topic_name(ros_name: str, node_name: str) -> str:
    """A topic name relative to a node without namespace: ``~/x`` -> ``node_name/x``, ``/x`` -> ``x``."""
    if ros_name.startswith("~"):
        return f"{node_name}/{ros_name[1:].lstrip('/')}"
    return ros_name.lstrip("/")


def dds_topic_name(ros_name: str, node_name: str = "glpma_fk") -> str:
    """``leg_lengths`` or ``/leg_lengths`` -> ``rt/leg_lengths``; ``~/assembly_modes`` ->
    ``rt/glpma_fk/assembly_modes`` (the node has no namespace)."""
    return "rt/" + expand_topic_name(ros_name, node_name)


def domain_id_from_env() -> int:
    """``ROS_DOMAIN_ID`` (default 0), as ROS 2 reads it."""
    raw = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if not raw:
        return 0
    try:
        value = int(raw)
    except ValueError:
        raise ValueError(f"ROS_DOMAIN_ID must be an integer, got {raw!r}") from None
    if not 0 <= value <= 232:
        raise ValueError(f"ROS_DOMAIN_ID must be in [0, 232], got {value}")
    return value


#: how long a reliable writer may block when the reader's history is full (Cyclone's default)
RELIABLE_MAX_BLOCKING = duration(milliseconds=100)


def ros_qos(msg_type, depth: int, transient_local: bool = False, spec: QosSpec | None = None) -> Qos:
    """Reliable, keep-last(depth), volatile (or transient-local) -- or the policies of ``spec``
    (:class:`~glpma_ros.node.qos.QosSpec`, e.g. with QoS overrides applied) -- with the type hash
    in USER_DATA."""
    spec = (spec or QosSpec(depth=int(depth), durability="transient_local" if transient_local else "volatile"))
    spec = spec.resolved()
    return Qos(
        Policy.Reliability.BestEffort if spec.reliability == "best_effort"
        else Policy.Reliability.Reliable(RELIABLE_MAX_BLOCKING),
        Policy.History.KeepAll if spec.history == "keep_all" else Policy.History.KeepLast(int(spec.depth)),
        Policy.Durability.TransientLocal if spec.durability == "transient_local" else Policy.Durability.Volatile,
        Policy.Userdata(f"typehash={type_hash(msg_type)};".encode()),
    )


class Participant:
    """A domain participant that creates ROS-compatible topics, readers and writers."""

    def __init__(self, domain_id: int | None = None):
        check_dds_transport()           # never unsecured when ROS_SECURITY_ENABLE=true (glpma_ros.node.security)
        self.domain_id = domain_id_from_env() if domain_id is None else int(domain_id)
        self.dp = DomainParticipant(self.domain_id)
        self._topics: dict[str, Topic] = {}

    def topic(self, ros_name: str, msg_type) -> Topic:
        name = dds_topic_name(ros_name)
        if name not in self._topics:
            self._topics[name] = Topic(self.dp, name, msg_type)
        return self._topics[name]

    def writer(self, ros_name: str, msg_type, depth: int = 10, transient_local: bool = False,
               qos: QosSpec | None = None) -> DataWriter:
        """``ros_name`` as :func:`dds_topic_name` takes it (``~/x`` is private to ``glpma_fk``;
        expand it with :func:`expand_topic_name` for another node name); ``qos`` replaces
        ``depth`` and ``transient_local`` when given."""
        return DataWriter(self.dp, self.topic(ros_name, msg_type), ros_qos(msg_type, depth, transient_local, qos))

    def reader(self, ros_name: str, msg_type, depth: int = 10, transient_local: bool = False,
               qos: QosSpec | None = None) -> DataReader:
        return DataReader(self.dp, self.topic(ros_name, msg_type), ros_qos(msg_type, depth, transient_local, qos))


def wait_for_match(endpoints, timeout_s: float, poll_s: float = 0.02) -> bool:
    """Wait until every writer has a matched reader and every reader a matched writer."""
    deadline = time.monotonic() + timeout_s

    def matched(ep) -> bool:
        if isinstance(ep, DataWriter):
            return bool(ep.get_matched_subscriptions())
        return bool(ep.get_matched_publications())

    while time.monotonic() < deadline:
        if all(matched(ep) for ep in endpoints):
            return True
        time.sleep(poll_s)
    return all(matched(ep) for ep in endpoints)


def reader_waitset(participant, readers) -> tuple[WaitSet, GuardCondition]:
    """A wait set that wakes when any of ``readers`` has a sample, or when the returned
    guard condition is set (to stop the thread waiting on it)."""
    guard = GuardCondition(participant.dp)
    waitset = WaitSet(participant.dp)
    any_state = SampleState.Any | ViewState.Any | InstanceState.Any
    for reader in readers:
        waitset.attach(ReadCondition(reader, any_state))
    waitset.attach(guard)
    return waitset, guard
