"""``glpma-fk node``: run the estimator node over rclpy or over plain Cyclone DDS.

``--transport auto`` (the default) takes rclpy when it can be imported (ROS 2
sourced), Cyclone DDS otherwise.  Everything after ``--ros-args`` is the same
for both transports.
"""
from __future__ import annotations

import importlib
import sys

from ..errors import GlpmaError
from . import qos
from .params import PARAMETERS
from .ros_args import ROS_ARGS_HELP, TRANSPORTS, check_params_files, split_transport


def rclpy_available() -> bool:
    try:
        importlib.import_module("rclpy")
    except Exception:  # noqa: BLE001 - ImportError, or a broken ROS environment
        return False
    return True


def usage() -> str:
    """``glpma-fk node --help``: the syntax and every declared parameter."""
    lines = ["usage: glpma-fk node [--transport auto|rclpy|dds] [--ros-args -p NAME:=VALUE ... "
             "--params-file FILE]", "",
             "Run the glpma_fk node: leg lengths in, poses out (topics in metres). SIGINT/SIGTERM stop it; "
             "SIGHUP (DDS transport) re-reads the --ros-args, params files included, and applies what changed.",
             "", "options:",
             "  -h, --help            print this help and exit",
             "  --transport auto|rclpy|dds",
             "                        rclpy (ROS 2 sourced) or plain Cyclone DDS; auto: rclpy when importable",
             *ROS_ARGS_HELP, "", "parameters:"]
    for spec in PARAMETERS:
        default = spec.default if spec.default != [] else "[]"
        extra = f" ({spec.constraints})" if spec.constraints else ""
        lines.append(f"  {spec.name} ({spec.type}, default {default}): {spec.description}{extra}")
    lines.append(f"  {qos.PREFIX}<topic>.<{'|'.join(qos.ENTITIES)}>.<{'|'.join(qos.POLICIES)}>: the QoS of one "
                 "endpoint, as rclpy's QoSOverridingOptions reads it (topic fully qualified, e.g. /leg_lengths; "
                 "read-only)")
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    head = argv[:argv.index("--ros-args")] if "--ros-args" in argv else argv
    if "-h" in head or "--help" in head:
        print(usage())
        return 0
    try:   # a params-file mistake (e.g. a manipulator YAML) in one line, whatever the transport
        check_params_files(argv)
    except GlpmaError as exc:
        print(f"glpma-fk node: error: {exc}", file=sys.stderr)
        return 2
    transport, rest = split_transport(argv)
    if transport not in TRANSPORTS:
        print(f"glpma-fk node: error: --transport must be one of {', '.join(TRANSPORTS)}, got {transport!r}",
              file=sys.stderr)
        return 2
    if transport == "auto":
        transport = "rclpy" if rclpy_available() else "dds"
    if transport == "rclpy":
        if not rclpy_available():
            print("glpma-fk node: error: rclpy is not importable (source ROS 2 Jazzy first, "
                  "or use --transport dds)", file=sys.stderr)
            return 2
        from .ros_node import main as ros_main  # needs rclpy (a sourced ROS 2): optional, imported here
        return ros_main(rest)
    try:
        from .dds.node import main as dds_main  # needs cyclonedds: optional here, imported where used
    except ImportError as exc:
        print(f"glpma-fk node: error: the DDS transport needs the cyclonedds Python package ({exc}); "
              f"pip install cyclonedds, or source ROS 2 and use --transport rclpy", file=sys.stderr)
        return 2
    return dds_main(rest)


if __name__ == "__main__":
    sys.exit(main())
