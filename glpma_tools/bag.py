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

This module is the command line (:func:`main`, :func:`run`); the run itself is
:mod:`glpma_tools.bag_run` (the messages' wire form: the node's codec, :mod:`glpma_ros.node.dds.cdr`).
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
import textwrap
from pathlib import Path

from glpma_ros.node import params as P
from glpma_ros.node.ros_args import ROS_ARGS_HELP, parse_ros_args
from glpma_ros.cli import OneLineParser
from glpma_ros.errors import GlpmaError, InputError

from .bag_run import BagRun, topic_name
from .extras import require

PROG = "glpma-fk bag"
STORAGES = ("mcap", "sqlite3")

#: offline time budget per input: the largest the parameter accepts (ms)
OFFLINE_BUDGET_MS = P.SPECS["time_budget_ms"].range[1]
#: width of the --help texts
HELP_WIDTH = 100


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
