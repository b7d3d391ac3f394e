"""Quality of service of the node's topics, and its overrides the ROS 2 way.

ROS 2 lets a params file change a topic's QoS without touching code ("QoS overrides", ROS 2 design
article *Quality of Service policies configurability*, implemented by rclpy's
``QoSOverridingOptions``): every publisher and subscription created with the options declares one
read-only parameter per overridable policy,

    qos_overrides.<fully qualified topic>.<publisher|subscription>.<policy>

whose default is the QoS the code asked for, and takes its value from the params file (or ``-p``)
when the node starts.  The ``glpma_fk`` node declares :data:`POLICIES` (rclpy's default set --
history, depth, reliability -- and durability) for every topic it reads or writes.  The rclpy
node lets rclpy do it (:mod:`.ros_node`); the Cyclone DDS transport reads the same keys here
(:func:`resolve`), so one params file means the same on both::

    glpma_fk:
      ros__parameters:
        qos_overrides:
          /leg_lengths:
            subscription:
              reliability: best_effort
              depth: 1

The defaults (:data:`DEFAULT`, :func:`node_endpoints`): reliable, keep-last ``qos_depth``, volatile
-- the ROS default profile -- ``/tf`` keep-last 100 (tf2_ros's broadcaster), ``~/assembly_modes``
keep-last 1 transient-local (latched).  ``qos_depth`` still sets the depth of every other topic; an
override of ``depth`` for one topic goes on top of it.  No ROS import here.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from ..errors import InputError

#: parameter names of the overrides start with this
PREFIX = "qos_overrides."
PUBLISHER, SUBSCRIPTION = "publisher", "subscription"
ENTITIES = (PUBLISHER, SUBSCRIPTION)
#: values of the enumerated policies, as rclpy spells them (the lower-case names of its enums);
#: ``system_default`` is left to the middleware, which for Cyclone DDS is the first value listed
RELIABILITY = ("reliable", "best_effort", "system_default")
HISTORY = ("keep_last", "keep_all", "system_default")
DURABILITY = ("volatile", "transient_local", "system_default")
#: the overridable policies: rclpy's QoSOverridingOptions.with_default_policies() and durability
POLICIES = ("history", "depth", "reliability", "durability")
_CHOICES = {"reliability": RELIABILITY, "history": HISTORY, "durability": DURABILITY}
#: keep-last depth of /tf, as tf2_ros's TransformBroadcaster has it (DynamicBroadcasterQoS)
TF_DEPTH = 100
#: the largest depth accepted (the same bound as the qos_depth parameter)
MAX_DEPTH = 10000


@dataclass(frozen=True)
class QosSpec:
    """One endpoint's QoS in rclpy's terms (the policies this node lets a user override)."""

    reliability: str = "reliable"
    history: str = "keep_last"
    depth: int = 10
    durability: str = "volatile"

    def resolved(self) -> "QosSpec":
        """``system_default`` replaced by what Cyclone DDS (and rmw_cyclonedds_cpp) use for it."""
        return replace(self, reliability="reliable" if self.reliability == "system_default" else self.reliability,
                       history="keep_last" if self.history == "system_default" else self.history,
                       durability="volatile" if self.durability == "system_default" else self.durability)


def fully_qualified(ros_name: str, node_name: str) -> str:
    """The topic name rclpy puts in the key, for a node without namespace: ``leg_lengths`` ->
    ``/leg_lengths``, ``~/markers`` -> ``/glpma_fk/markers``, ``/tf`` -> ``/tf``."""
    if ros_name.startswith("~"):
        return f"/{node_name}/{ros_name[1:].lstrip('/')}"
    return "/" + ros_name.lstrip("/")


def key(topic_fqn: str, entity: str, policy: str) -> str:
    """``qos_overrides./leg_lengths.subscription.reliability``."""
    return f"{PREFIX}{topic_fqn}.{entity}.{policy}"


def split_overrides(overrides: dict) -> tuple[dict, dict]:
    """``(qos overrides, the other parameters)`` of a parameter-name -> value mapping."""
    qos = {k: v for k, v in overrides.items() if k.startswith(PREFIX)}
    return qos, {k: v for k, v in overrides.items() if not k.startswith(PREFIX)}


def _value(name: str, policy: str, value):
    if policy == "depth":
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(f"parameter '{name}' must be an integer, got {value!r}")
        if not 1 <= value <= MAX_DEPTH:
            raise InputError(f"parameter '{name}' must be >= 1 and <= {MAX_DEPTH}, got {value}")
        return value
    if not isinstance(value, str) or value.lower() not in _CHOICES[policy]:
        raise InputError(f"parameter '{name}' must be one of {', '.join(_CHOICES[policy])}, got {value!r}")
    return value.lower()


def apply(default: QosSpec, overrides: dict, topic_fqn: str, entity: str) -> QosSpec:
    """``default`` with the overrides of one endpoint applied; :class:`InputError` names a bad value."""
    changes = {}
    for policy in POLICIES:
        name = key(topic_fqn, entity, policy)
        if name in overrides:
            changes[policy] = _value(name, policy, overrides[name])
    return replace(default, **changes)


def node_endpoints(depth: int, input_topic: str) -> dict:
    """``{(ROS topic name, entity): default QosSpec}`` of every endpoint of the node, for a
    ``qos_depth`` of ``depth`` and input topic ``input_topic`` (``leg_lengths`` or ``joint_states``)."""
    base = QosSpec(depth=depth)
    return {
        (input_topic, SUBSCRIPTION): base,
        ("~/request_assembly_modes", SUBSCRIPTION): base,
        ("pose_estimate", PUBLISHER): base,
        ("/tf", PUBLISHER): replace(base, depth=max(depth, TF_DEPTH)),
        ("pose_estimate_cov", PUBLISHER): base,
        ("twist_estimate", PUBLISHER): base,
        ("~/markers", PUBLISHER): base,
        ("~/mechanism_joint_states", PUBLISHER): base,
        ("/diagnostics", PUBLISHER): base,
        ("~/assembly_modes", PUBLISHER): QosSpec(depth=1, durability="transient_local"),
    }


def resolve(overrides: dict, depth: int, input_topic: str, node_name: str,
            topic_of=lambda name: name) -> tuple[dict, list[str]]:
    """Every endpoint's QoS with the overrides applied, as the DDS transport uses them:
    ``({(ROS topic name, entity): QosSpec}, warnings)``.  ``topic_of(name)`` is the topic after
    remapping; the keys use its fully qualified form, as rclpy's do.  An override that names no
    endpoint of the node or no overridable policy is a warning (rclpy ignores a parameter nobody
    declares); a bad value an :class:`InputError`."""
    qos_overrides, _ = split_overrides(overrides)
    out, used = {}, set()
    for (name, entity), default in node_endpoints(depth, input_topic).items():
        fqn = fully_qualified(topic_of(name), node_name)
        out[(name, entity)] = apply(default, qos_overrides, fqn, entity)
        used.update(key(fqn, entity, policy) for policy in POLICIES)
    warnings = [f"ignoring QoS override '{k}' (no such topic, entity or policy of {node_name}; "
                f"overridable: {', '.join(POLICIES)})" for k in qos_overrides if k not in used]
    return out, warnings
