"""Topics, QoS and endpoints as a ROS 2 Jazzy node on ``rmw_cyclonedds_cpp`` has them.

ROS topic ``name`` travels as DDS topic ``rt/name``; each reader and writer
carries ``typehash=<RIHS01 hash>;`` as USER_DATA.  QoS: reliable, keep-last
(depth), volatile -- the ROS default profile.
"""
from __future__ import annotations

import os
import time

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from .messages import type_hash

LEG_LENGTHS = "leg_lengths"
POSE_ESTIMATE = "pose_estimate"
DIAGNOSTICS = "/diagnostics"


def dds_topic_name(ros_name: str) -> str:
    """``leg_lengths`` or ``/leg_lengths`` -> ``rt/leg_lengths`` (the node has no namespace)."""
    return "rt/" + ros_name.lstrip("/")


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


def ros_qos(msg_type, depth: int) -> Qos:
    """Reliable, keep-last(depth), volatile, with the type hash in USER_DATA."""
    return Qos(
        Policy.Reliability.Reliable(duration(milliseconds=100)),
        Policy.History.KeepLast(int(depth)),
        Policy.Durability.Volatile,
        Policy.Userdata(f"typehash={type_hash(msg_type)};".encode()),
    )


class Participant:
    """A domain participant that creates ROS-compatible topics, readers and writers."""

    def __init__(self, domain_id: int | None = None):
        self.domain_id = domain_id_from_env() if domain_id is None else int(domain_id)
        self.dp = DomainParticipant(self.domain_id)
        self._topics: dict[str, Topic] = {}

    def topic(self, ros_name: str, msg_type) -> Topic:
        name = dds_topic_name(ros_name)
        if name not in self._topics:
            self._topics[name] = Topic(self.dp, name, msg_type)
        return self._topics[name]

    def writer(self, ros_name: str, msg_type, depth: int = 10) -> DataWriter:
        return DataWriter(self.dp, self.topic(ros_name, msg_type), ros_qos(msg_type, depth))

    def reader(self, ros_name: str, msg_type, depth: int = 10) -> DataReader:
        return DataReader(self.dp, self.topic(ros_name, msg_type), ros_qos(msg_type, depth))


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
