"""Reading a recorded rosbag2 (``rosbags``, the ``bag`` extra, imported where used): :func:`open_bag`, and the
input messages decoded by the node's codec (:mod:`.cdr`) where rosbag2 recorded them as little-endian CDR,
else by ``rosbags``' typestore.  Read by ``glpma-fk bag`` and ``glpma-fk calibrate``."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import InputError
from . import cdr

#: the ROS 2 types read from bags
FLOAT64_MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
JOINT_STATE = "sensor_msgs/msg/JointState"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
#: nanoseconds per second (builtin_interfaces/msg/Time)
NS_PER_S = 1_000_000_000


def open_bag(path: Path):
    """An open rosbags Reader (read-only), or :class:`InputError`."""
    from rosbags.rosbag2 import Reader  # the bag extra: optional, imported where used
    if not path.exists():
        raise InputError(f"input bag {path} does not exist")
    try:
        reader = Reader(path)
        reader.open()
    except Exception as exc:  # noqa: BLE001 - ReaderError, OSError, or a malformed file
        raise InputError(f"cannot read bag {path}: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
                         ) from None
    return reader


def decode_float64_multi_array(raw, typestore) -> np.ndarray:
    """``data`` of a std_msgs/msg/Float64MultiArray: read by the node's codec (:mod:`glpma_ros.node.dds.cdr`)
    when little-endian CDR, as rosbag2 records it; otherwise by ``rosbags``."""
    if cdr.little_endian_cdr(raw):
        return np.asarray(cdr.float64_multi_array_data(raw), dtype=float)
    return np.asarray(typestore.deserialize_cdr(raw, FLOAT64_MULTI_ARRAY).data, dtype=float)


def decode_joint_state(raw, typestore) -> tuple:
    """``(names, positions, header.stamp in ns)`` of a sensor_msgs/msg/JointState (as above)."""
    if cdr.little_endian_cdr(raw):
        stamp_ns, names, positions, _ = cdr.joint_state_fields(raw)
        return list(names), np.asarray(positions, dtype=float), stamp_ns
    msg = typestore.deserialize_cdr(raw, JOINT_STATE)
    stamp = msg.header.stamp
    return list(msg.name), np.asarray(msg.position, dtype=float), stamp.sec * NS_PER_S + stamp.nanosec
