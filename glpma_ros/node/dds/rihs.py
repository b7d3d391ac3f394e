"""RIHS01 type hashes (REP 2011) of the ROS 2 messages the node uses, computed.

A ROS 2 Jazzy type hash is the SHA-256 of the type's description (its fields and, sorted by
name, the descriptions of every type it refers to) written as JSON in one canonical way
(``rosidl_generator_type_description``: ``separators=(', ', ': ')``, keys in declaration
order, default values left out).  :func:`type_hash` gives the hash of every type the node
publishes or subscribes to -- including ``std_msgs/msg/Empty``, whose IDL struct carries the
member ``uint8 structure_needs_at_least_one_member`` that rosidl adds to an empty message --
identical to the one Jazzy's ``rosidl_generator_type_description`` writes for the Jazzy
``.msg`` files and that ``ros2 topic info -v`` reports.  ``messages.TYPE_HASHES`` holds the
results, the tests compare the two.  Pure Python.
"""
from __future__ import annotations

import hashlib
import json

#: type_description_interfaces/msg/FieldType ids of the primitive types used here
FIELD_TYPE_IDS = {"int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7, "int64": 8,
                  "uint64": 9, "float32": 10, "float64": 11, "char": 13, "bool": 15, "byte": 16,
                  "string": 17}
NESTED_TYPE = 1
#: added to the id of a fixed-size array (``T[N]``, capacity N)
ARRAY_OFFSET = 48
#: added to the id of an unbounded sequence (``T[]``)
UNBOUNDED_SEQUENCE_OFFSET = 144

#: the .msg definitions (Jazzy), fields in order; constants are not part of the hash
DEFINITIONS = {
    "builtin_interfaces/msg/Time": [("sec", "int32"), ("nanosec", "uint32")],
    "std_msgs/msg/Header": [("stamp", "builtin_interfaces/msg/Time"), ("frame_id", "string")],
    "std_msgs/msg/Empty": [("structure_needs_at_least_one_member", "uint8")],
    "std_msgs/msg/MultiArrayDimension": [("label", "string"), ("size", "uint32"), ("stride", "uint32")],
    "std_msgs/msg/MultiArrayLayout": [("dim", "std_msgs/msg/MultiArrayDimension[]"), ("data_offset", "uint32")],
    "std_msgs/msg/Float64MultiArray": [("layout", "std_msgs/msg/MultiArrayLayout"), ("data", "float64[]")],
    "geometry_msgs/msg/Point": [("x", "float64"), ("y", "float64"), ("z", "float64")],
    "geometry_msgs/msg/Quaternion": [("x", "float64"), ("y", "float64"), ("z", "float64"), ("w", "float64")],
    "geometry_msgs/msg/Pose": [("position", "geometry_msgs/msg/Point"),
                               ("orientation", "geometry_msgs/msg/Quaternion")],
    "geometry_msgs/msg/PoseStamped": [("header", "std_msgs/msg/Header"), ("pose", "geometry_msgs/msg/Pose")],
    "geometry_msgs/msg/PoseArray": [("header", "std_msgs/msg/Header"), ("poses", "geometry_msgs/msg/Pose[]")],
    "sensor_msgs/msg/JointState": [("header", "std_msgs/msg/Header"), ("name", "string[]"),
                                   ("position", "float64[]"), ("velocity", "float64[]"),
                                   ("effort", "float64[]")],
    "diagnostic_msgs/msg/KeyValue": [("key", "string"), ("value", "string")],
    "diagnostic_msgs/msg/DiagnosticStatus": [("level", "byte"), ("name", "string"), ("message", "string"),
                                             ("hardware_id", "string"),
                                             ("values", "diagnostic_msgs/msg/KeyValue[]")],
    "diagnostic_msgs/msg/DiagnosticArray": [("header", "std_msgs/msg/Header"),
                                            ("status", "diagnostic_msgs/msg/DiagnosticStatus[]")],
    # the node's further outputs: TF, covariance, twist, markers
    "builtin_interfaces/msg/Duration": [("sec", "int32"), ("nanosec", "uint32")],
    "std_msgs/msg/ColorRGBA": [("r", "float32"), ("g", "float32"), ("b", "float32"), ("a", "float32")],
    "geometry_msgs/msg/Vector3": [("x", "float64"), ("y", "float64"), ("z", "float64")],
    "geometry_msgs/msg/Transform": [("translation", "geometry_msgs/msg/Vector3"),
                                    ("rotation", "geometry_msgs/msg/Quaternion")],
    "geometry_msgs/msg/TransformStamped": [("header", "std_msgs/msg/Header"), ("child_frame_id", "string"),
                                           ("transform", "geometry_msgs/msg/Transform")],
    "tf2_msgs/msg/TFMessage": [("transforms", "geometry_msgs/msg/TransformStamped[]")],
    "geometry_msgs/msg/PoseWithCovariance": [("pose", "geometry_msgs/msg/Pose"), ("covariance", "float64[36]")],
    "geometry_msgs/msg/PoseWithCovarianceStamped": [("header", "std_msgs/msg/Header"),
                                                    ("pose", "geometry_msgs/msg/PoseWithCovariance")],
    "geometry_msgs/msg/Twist": [("linear", "geometry_msgs/msg/Vector3"), ("angular", "geometry_msgs/msg/Vector3")],
    "geometry_msgs/msg/TwistStamped": [("header", "std_msgs/msg/Header"), ("twist", "geometry_msgs/msg/Twist")],
    "sensor_msgs/msg/CompressedImage": [("header", "std_msgs/msg/Header"), ("format", "string"),
                                        ("data", "uint8[]")],
    "visualization_msgs/msg/UVCoordinate": [("u", "float32"), ("v", "float32")],
    "visualization_msgs/msg/MeshFile": [("filename", "string"), ("data", "uint8[]")],
    "visualization_msgs/msg/Marker": [
        ("header", "std_msgs/msg/Header"), ("ns", "string"), ("id", "int32"), ("type", "int32"),
        ("action", "int32"), ("pose", "geometry_msgs/msg/Pose"), ("scale", "geometry_msgs/msg/Vector3"),
        ("color", "std_msgs/msg/ColorRGBA"), ("lifetime", "builtin_interfaces/msg/Duration"),
        ("frame_locked", "bool"), ("points", "geometry_msgs/msg/Point[]"), ("colors", "std_msgs/msg/ColorRGBA[]"),
        ("texture_resource", "string"), ("texture", "sensor_msgs/msg/CompressedImage"),
        ("uv_coordinates", "visualization_msgs/msg/UVCoordinate[]"), ("text", "string"),
        ("mesh_resource", "string"), ("mesh_file", "visualization_msgs/msg/MeshFile"),
        ("mesh_use_embedded_materials", "bool")],
    "visualization_msgs/msg/MarkerArray": [("markers", "visualization_msgs/msg/Marker[]")],
}


def _field_type(type_name: str) -> tuple[dict, str]:
    """``T``, ``T[]`` (unbounded sequence) or ``T[N]`` (array of N) as a FieldType."""
    base, capacity, offset = type_name, 0, 0
    if type_name.endswith("]"):
        base, size = type_name[:-1].split("[")
        capacity, offset = (int(size), ARRAY_OFFSET) if size else (0, UNBOUNDED_SEQUENCE_OFFSET)
    type_id, nested = (FIELD_TYPE_IDS[base], "") if base in FIELD_TYPE_IDS else (NESTED_TYPE, base)
    return {"type_id": type_id + offset, "capacity": capacity, "string_capacity": 0,
            "nested_type_name": nested}, nested


def _description(name: str) -> tuple[dict, set]:
    fields, refs = [], set()
    for field_name, type_name in DEFINITIONS[name]:
        field_type, nested = _field_type(type_name)
        fields.append({"name": field_name, "type": field_type})
        if nested:
            refs.add(nested)
    return {"type_name": name, "fields": fields}, refs


def type_description(name: str) -> dict:
    """The hashed form of ``name``'s TypeDescription (default values left out)."""
    top, todo = _description(name)
    seen: set = set()
    todo = list(todo)
    while todo:
        ref = todo.pop()
        if ref not in seen:
            seen.add(ref)
            todo.extend(_description(ref)[1])
    return {"type_description": top,
            "referenced_type_descriptions": [_description(ref)[0] for ref in sorted(seen)]}


def type_hash(name: str) -> str:
    """``RIHS01_<sha256>`` of ROS type ``name`` (e.g. ``std_msgs/msg/Empty``)."""
    text = json.dumps(type_description(name), skipkeys=False, ensure_ascii=True, check_circular=True,
                      allow_nan=False, indent=None, separators=(", ", ": "), sort_keys=False)
    return "RIHS01_" + hashlib.sha256(text.encode("utf-8")).hexdigest()
