"""Which topic the node reads its input from: a name that says what it carries.

* ``joint_states`` (``sensor_msgs/JointState``, ``input_type: joint_state``) for every manipulator;
* ``leg_lengths`` (``std_msgs/Float64MultiArray``, metres) for the length-actuated ones (3-RPR, hexapods);
* ``actuator_positions`` (``std_msgs/Float64MultiArray``, radians for revolute and metres for prismatic
  actuators, in leg order) for the actuated families (``delta``, ``rus_6``, ``linear_delta``, ...:
  :mod:`glpma_ros.models.families`).

Every name is remappable (``--ros-args -r actuator_positions:=/my/topic``).  No ROS import.
"""
from __future__ import annotations

from . import params as P

LEG_LENGTHS = "leg_lengths"
JOINT_STATES = "joint_states"
ACTUATOR_POSITIONS = "actuator_positions"


def input_topic(input_type: str, actuated: bool) -> str:
    """The input topic for ``input_type`` (the parameter) and a model that is ``actuated`` or not."""
    if input_type == P.INPUT_JOINT_STATE:
        return JOINT_STATES
    return ACTUATOR_POSITIONS if actuated else LEG_LENGTHS


def model_is_actuated(model) -> bool:
    return bool(getattr(model, "actuated", False))


def readings_in_si(model, values) -> list:
    """What goes on the input topic for ``values`` in the config's units: leg lengths in metres; an actuated
    family's actuator positions in radians (metres for prismatic ones)."""
    if model_is_actuated(model):
        return model.readings_to_si(values).tolist()
    return [float(v) * float(model.metres_per_unit) for v in values]


def config_is_actuated(config_name: str) -> bool:
    """The manipulator config ``config_name`` (a path or a shipped name) is an actuated family's; False
    when it cannot be read (the node's start reports that)."""
    from ..config import load_document, resolve_config
    from ..models.families import is_family
    try:
        return is_family(load_document(resolve_config(config_name)))
    except Exception:  # noqa: BLE001 - an unreadable config is reported where it is loaded
        return False
