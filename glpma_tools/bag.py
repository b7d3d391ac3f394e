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
(``OFFLINE_BUDGET_MS``, 60,000 ms per input, far beyond any solve), so that every status is
decided by the work done -- also when the node's params file sets a real-time budget.

A fleet's recordings: ``glpma-fk bag INPUT [INPUT ...] --out-dir DIR`` (an INPUT may be a
directory holding bags) writes one output bag per input, ``DIR/<input's name>``, each with a
service of its own (the warm start begins afresh with every bag), on local worker processes
(``--workers``) or a Dask cluster (``--scheduler``; :mod:`glpma_tools.parallel`), and prints a
summary table; every engine writes the same bags.

Exit status: 0 done, 1 when an input bag had no input that converged (or a worker failed),
2 bad input, 130 interrupted.

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
import os
import sys
import textwrap
import time
from pathlib import Path

from glpma_ros.cli.api import OneLineParser, command_main
from glpma_ros.errors import InputError
from glpma_ros.node import params as P
from glpma_ros.node.input_topic import config_is_actuated
from glpma_ros.node.input_topic import input_topic as node_input_topic
from glpma_ros.node.ros_args import ROS_ARGS_HELP, parse_ros_args

from .bag_outcome import OFFLINE_BUDGET_MS, Summary
from .bag_run import BagJob, make_logger, process_bag, topic_name
from .extras import require
from .parallel import EngineError, engine_name, run_tasks
from .tables import add_summary_options, fmt, table

PROG = "glpma-fk bag"
STORAGES = ("mcap", "sqlite3")
#: files that are a bag by themselves (rosbags opens a single MCAP or SQLite3 file too)
BAG_FILE_SUFFIXES = (".mcap", ".db3")
#: exit status when an input bag had no input that converged (or a worker failed)
EXIT_NONE_CONVERGED = 1
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
    lines += ["", textwrap.fill("exit status: 0 done; 1 an input bag had no input that converged (the reasons are "
                                "in the summary), or a worker failed; 2 bad input (one line on stderr); "
                                "130 interrupted.", HELP_WIDTH)]
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter,
        usage=f"{PROG} INPUT OUTPUT [options] [--ros-args -p NAME:=VALUE ... --params-file FILE]\n"
              f"       {PROG} INPUT [INPUT ...] --out-dir DIR [--workers N | --scheduler tcp://HOST:PORT] [options] "
              f"[--ros-args ...]",
        description=textwrap.fill(
                    "Estimate the platform pose for every leg_lengths (std_msgs/msg/Float64MultiArray) or "
                    "joint_states (sensor_msgs/msg/JointState) message of a recorded rosbag2 (MCAP or SQLite3) "
                    "with the node's estimator and parameters, and write a new bag: every input message copied "
                    "unchanged, plus pose_estimate (geometry_msgs/msg/PoseStamped), /tf (tf2_msgs/msg/TFMessage) "
                    "and ~/status (diagnostic_msgs/msg/DiagnosticStatus) per input. Topics are in metres. "
                    "With --out-dir, every INPUT (a bag, or a directory of bags) gets its own output bag "
                    "DIR/<name>, the bags run in parallel, and a summary table follows.",
                    HELP_WIDTH, break_on_hyphens=False),
        epilog=_parameter_help())
    p.add_argument("paths", nargs="+", metavar="INPUT",
                   help="rosbag2 directory (or a single .mcap / .db3 file), read only; then OUTPUT, the rosbag2 "
                        "directory to create -- or, with --out-dir, any number of inputs and directories of bags")
    p.add_argument("--out-dir", default=None, metavar="DIR",
                   help="several inputs: write the output bag of each INPUT as DIR/<its name> (created)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="with --out-dir: bags processed at once in local worker processes (default: all cores, at most "
                        "one per bag; 1 = one after the other in this process)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="with --out-dir: run the bags on this Dask distributed scheduler instead (dask.distributed "
                        "from glpma_ros[map]; the workers need glpma_ros[bag] and the same paths: INPUT and DIR on a "
                        "shared file system)")
    p.add_argument("--storage", choices=STORAGES, default=None, help="storage of OUTPUT (default: INPUT's)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing OUTPUT (refused by default)")
    p.add_argument("--budget-ms", type=float, default=None, metavar="MS",
                   help=f"time budget of one input (parameter time_budget_ms; default {OFFLINE_BUDGET_MS:g}, its "
                        f"maximum, so that statuses depend on the work done only; a time_budget_ms in the "
                        f"parameters is replaced)")
    p.add_argument("--input-type", choices=P.INPUT_TYPES, default=None,
                   help="input message type (default: parameter input_type, float64_multi_array)")
    p.add_argument("--legs-topic", default=None, metavar="TOPIC",
                   help="Float64MultiArray input topic (default: the node's, leg_lengths -- i.e. /leg_lengths -- or "
                        "actuator_positions for an actuated family's config)")
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
    add_summary_options(p)
    return p


@command_main(prog=PROG)
def main(argv=None) -> int:
    """Exit status: see the module's docstring (a failed worker's :class:`EngineError`: 1)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    require("bag", PROG)
    ros = parse_ros_args(argv)
    args = build_parser().parse_args(ros.other)
    if args.scheduler:              # Dask comes with the map extra
        require("map", PROG, modules=("dask", "distributed"))
    return run(args, ros)


# -- inputs and outputs ---------------------------------------------------------------------------------

def is_bag(path: Path) -> bool:
    """A rosbag2 directory (with its metadata.yaml) or a single MCAP / SQLite3 file."""
    return (path.is_dir() and (path / "metadata.yaml").is_file()) or \
        (path.is_file() and path.suffix in BAG_FILE_SUFFIXES)


def expand_inputs(paths) -> list:
    """The input bags: each path a bag, or a directory whose entries that are bags are taken (sorted
    by name)."""
    bags = []
    for text in paths:
        path = Path(text)
        if not path.exists():
            raise InputError(f"input bag {path} does not exist")
        if is_bag(path) or not path.is_dir():
            bags.append(path)
            continue
        inside = sorted(p for p in path.iterdir() if is_bag(p))
        if not inside:
            raise InputError(f"{path} is neither a bag nor a directory holding bags")
        bags += inside
    return bags


def _check_output(input_path: Path, output_path: Path, overwrite: bool) -> None:
    src, dst = input_path.resolve(), output_path.resolve()
    if dst == src or src.is_relative_to(dst) or dst.is_relative_to(src):
        raise InputError(f"OUTPUT {output_path} must be outside INPUT {input_path}")
    if (output_path.exists() or output_path.is_symlink()) and not overwrite:
        raise InputError(f"{output_path} exists (--overwrite replaces it)")


def plan(args) -> list:
    """``[(input, output), ...]`` of the run, each checked."""
    if args.out_dir is None:
        if args.workers is not None or args.scheduler is not None:
            raise InputError("--workers and --scheduler run several bags: give them with --out-dir DIR")
        if len(args.paths) != 2:
            raise InputError(f"expected INPUT OUTPUT, got {len(args.paths)} path{'s' if len(args.paths) != 1 else ''}"
                             f" (several inputs: --out-dir DIR)")
        pairs = [(Path(args.paths[0]), Path(args.paths[1]))]
    else:
        if args.workers is not None and args.workers < 1:
            raise InputError("--workers must be at least 1")
        out_dir = Path(args.out_dir)
        pairs, names = [], {}
        for bag in expand_inputs(args.paths):
            name = bag.stem if bag.is_file() else bag.name
            if name in names:
                raise InputError(f"{bag} and {names[name]} would both write {out_dir / name}; rename one")
            names[name] = bag
            pairs.append((bag, out_dir / name))
    for input_path, output_path in pairs:
        _check_output(input_path, output_path, args.overwrite)
    return pairs


def run(args, ros) -> int:
    if not args.child_frame_id.strip():
        raise InputError("--child-frame-id must not be empty")
    pairs = plan(args)
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

    level = logging.getLevelName((ros.log_level or "warning").upper())
    level = level if isinstance(level, int) else logging.WARNING
    log = make_logger(ros.node_name, level)
    for warning in [*ros.warnings, *warnings]:
        log.warning(warning)
    if replaced is not None and replaced != budget:
        log.info(f"time_budget_ms:={replaced} of the parameters replaced by {budget:g} (--budget-ms)")

    name = ros.node_name
    input_type = values["input_type"]
    input_topic = (args.joint_states_topic if input_type == P.INPUT_JOINT_STATE else args.legs_topic or
                   node_input_topic(input_type, config_is_actuated(values["manipulator_config"])))
    job = BagJob(values, name, input_topic=topic_name(input_topic, name, ros.remaps),
                 pose_topic=topic_name(args.pose_topic, name, ros.remaps),
                 tf_topic=None if args.no_tf else topic_name(args.tf_topic, name, ros.remaps),
                 status_topic=topic_name(args.status_topic, name, ros.remaps),
                 child_frame_id=args.child_frame_id, storage=args.storage, log_level=level)
    service = job.service(log)             # the parameters and the config, checked once here
    if args.out_dir is None:
        (input_path, output_path), = pairs
        summary = process_bag(job, str(input_path), str(output_path), progress=not args.no_progress,
                              service=service)
        print(json.dumps(summary.as_dict()) if args.json else summary.text())
        return _exit_status([summary])
    return run_fleet(job, pairs, args)


def _exit_status(summaries) -> int:
    none = [s for s in summaries if s.converged == 0]
    for s in none:
        reasons = "; ".join(f"{n} {reason}" for reason, n in s.rejected.most_common(2))
        print(f"error: {PROG}: no input of {s.input} converged ({s.inputs} inputs on {s.input_topic}"
              f"{': ' + reasons if reasons else ''})", file=sys.stderr)
    return EXIT_NONE_CONVERGED if none else 0


# -- several bags ---------------------------------------------------------------------------------------

def run_fleet(job: BagJob, pairs: list, args) -> int:
    """Every (input, output) pair as a task on the engine; the summary table in the inputs' order."""
    from tqdm import tqdm  # the tools extra: optional, imported where used
    workers = min(os.cpu_count() or 1, len(pairs)) if args.workers is None else args.workers
    engine = engine_name(workers, args.scheduler)
    Path(args.out_dir).mkdir(parents=True, exist_ok=True)
    summaries: dict = {}
    t0 = time.perf_counter()
    with tqdm(total=len(pairs), unit="bag", file=sys.stderr, disable=None if not args.no_progress else True,
              dynamic_ncols=True, desc="bags") as bar:
        def done(summary: Summary):
            summaries[summary.input] = summary
            bar.update(1)
        try:
            run_tasks(process_bag, [(str(i), str(o)) for i, o in pairs], done, shared=(job,), workers=workers,
                      scheduler=args.scheduler)
        except EngineError as exc:
            raise EngineError(f"processing the bags failed on {exc}") from None
    elapsed = time.perf_counter() - t0
    ordered = [summaries[str(i)] for i, _ in pairs]
    fleet = FleetSummary(ordered, engine, elapsed)
    print(json.dumps(fleet.as_dict()) if args.json else fleet.text())
    return _exit_status(ordered)


class FleetSummary:
    """The bags of one run, and their totals."""

    def __init__(self, summaries: list, engine: str, elapsed_s: float):
        self.summaries, self.engine, self.elapsed_s = summaries, engine, elapsed_s

    def totals(self) -> dict:
        s = self.summaries
        converged = sum(b.converged for b in s)
        return {"bags": len(s), "messages": sum(b.messages for b in s), "inputs": sum(b.inputs for b in s),
                "converged": converged, "rejected": sum(sum(b.rejected.values()) for b in s),
                "assembly_mode_changes": sum(b.mode_changes for b in s), "elapsed_s": self.elapsed_s,
                "poses_per_s": converged / self.elapsed_s if self.elapsed_s > 0 else 0.0}

    def as_dict(self) -> dict:
        return {"engine": self.engine, "bags": [b.as_dict() for b in self.summaries], "total": self.totals()}

    def text(self) -> str:
        head = ("input", "output", "inputs", "converged", "rejected", "mode changes", "poses/s")
        rows = [(b.input, b.output, fmt(b.inputs), fmt(b.converged), fmt(sum(b.rejected.values())),
                 fmt(b.mode_changes), fmt(b.poses_per_s)) for b in self.summaries]
        t = self.totals()
        rows.append((f"total ({t['bags']} bags)", "", fmt(t["inputs"]), fmt(t["converged"]), fmt(t["rejected"]),
                     fmt(t["assembly_mode_changes"]), fmt(t["poses_per_s"])))
        lines = [table(head, rows, markdown=False),
                 f"{t['bags']} bags in {self.elapsed_s:.1f} s on {self.engine}"]
        for b in self.summaries:
            lines += [f"  {b.input}: rejected {n}: {reason}" for reason, n in b.rejected.most_common()]
            lines += [f"  {b.input}: not copied: {topic}: {why}" for topic, why in b.skipped_topics.items()]
        return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
