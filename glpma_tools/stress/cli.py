"""``glpma-fk stress``: the sections in order, the command line and where the figures go."""
from __future__ import annotations

import json
import math
import os
import shlex
import sys
import time
from pathlib import Path

from glpma_ros.cli.api import OneLineParser, command_main
from glpma_tools.timing import git_revision, machine

from . import flood, restarts
from .deadline import DEADLINE_BUDGETS_MS, deadlines
from .report import format_table, to_json, write_json
from .session import DEFAULT_PARAMS, RATE_HZ, REPO_ROOT, Session

SECTIONS = ("overload", "burst", "restarts", "deadline")
#: (full, --quick)
DEFAULTS = {"duration_s": (60.0, 3.0), "burst": (10_000, 2_000), "deadline_solves": (10_000, 300),
            "phase_s": (2.0, 1.0)}
#: where a full run of every section leaves its figures for the benchmark's Reliability section
RELIABILITY_JSON = REPO_ROOT / "doc" / "bench" / "reliability.json"
#: ROS_DOMAIN_ID range
MAX_DOMAIN = 232


def _shown(arg: str) -> str:
    """A path inside the repository as relative to it (the report names no local directories)."""
    path = Path(arg)
    return str(path.relative_to(REPO_ROOT)) if path.is_absolute() and path.is_relative_to(REPO_ROOT) else arg


def run(sections=SECTIONS, quick: bool = False, duration_s: float | None = None, rate_hz: float = RATE_HZ,
        burst_n: int | None = None, deadline_solves: int | None = None, phase_s: float | None = None,
        params_file=DEFAULT_PARAMS, extra_args=(), domain_id: int | None = None, log_dir=None,
        budgets_ms=DEADLINE_BUDGETS_MS, say=None) -> dict:
    """Every requested section; a JSON-able dict of figures and checks."""

    def pick(value, name):
        return DEFAULTS[name][1 if quick else 0] if value is None else value

    say = say or (lambda msg: None)
    t_start = time.perf_counter()
    res = {"date": time.strftime("%Y-%m-%d %H:%M %Z"), "quick": quick, "revision": git_revision(),
           "machine": machine(), "load_average_start": os.getloadavg(), "sections": {}}
    session = Session(params_file, extra_args, domain_id, log_dir, say)
    res["log_dir"] = str(session.log_dir)
    if any(s != "deadline" for s in sections):
        res["node"] = {"command": shlex.join(["python", "-m", "glpma_ros.node.dds.node", "--ros-args",
                                              *map(_shown, session.ros_args)]),
                       "domain": session.domain_id, "manipulator": session.model.kind,
                       "time_budget_ms": session.params["time_budget_ms"], "qos_depth": session.params["qos_depth"]}
        try:
            session.start()
            if "overload" in sections:
                res["sections"]["overload"] = flood.overload(session, pick(duration_s, "duration_s"), rate_hz)
            if "burst" in sections:
                res["sections"]["burst"] = flood.burst(session, pick(burst_n, "burst"))
            if "restarts" in sections:
                p = pick(phase_s, "phase_s")
                res["sections"]["controller_restart"] = restarts.controller_restart(session, p)
                res["sections"]["large_jump"] = restarts.large_jump(session, p)
                res["sections"]["node_restart"] = restarts.node_restart(session, p)
            res["node"]["startup_s"] = session.startup_s
        finally:
            session.close()
    if "deadline" in sections:
        res["sections"]["deadline"] = {
            "manipulator": session.model.kind,
            "rows": deadlines(session.model, budgets_ms, pick(deadline_solves, "deadline_solves"),
                              session.plan.start_variables(), say)}
    res["load_average_end"] = os.getloadavg()
    res["wall_s"] = time.perf_counter() - t_start
    res["passed"] = all(all(s.get("checks", {}).values()) for s in res["sections"].values())
    res["expectations_met"] = all(all(s.get("expectations", {}).values()) for s in res["sections"].values())
    return res


def build_parser() -> OneLineParser:
    p = OneLineParser(prog="glpma-fk stress",
                      description="The glpma_fk node under overload, bursts, restarts and deadlines.")
    p.add_argument("--quick", action="store_true", help="a few seconds per section")
    p.add_argument("--sections", nargs="+", choices=SECTIONS, default=list(SECTIONS),
                   help="run only these sections (default: all)")
    p.add_argument("--duration", type=float, help="seconds of overload (default 60; --quick 3)")
    p.add_argument("--rate", type=float, default=RATE_HZ, help="overload input rate, Hz (default 1000)")
    p.add_argument("--burst", type=int, help="messages in the burst (default 10000; --quick 2000)")
    p.add_argument("--phase", type=float, help="seconds of each restart/jump phase (default 2; --quick 1)")
    p.add_argument("--deadline-solves", type=int, help="Estimator solves per budget and case (default 10000)")
    p.add_argument("--budgets-ms", type=float, nargs="+", default=list(DEADLINE_BUDGETS_MS),
                   help="time budgets of the deadline section, ms")
    p.add_argument("--params-file", type=Path, default=DEFAULT_PARAMS, help="the node's parameters")
    p.add_argument("-p", dest="params", action="append", default=[], metavar="NAME:=VALUE",
                   help="more node parameters (as after --ros-args -p)")
    p.add_argument("--domain", type=int,
                   help="ROS_DOMAIN_ID (default: one this run claims, that no other run on the host uses)")
    p.add_argument("--log-dir", type=Path, help="where the node's stdout/stderr go (default a temporary directory)")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object on stdout")
    p.add_argument("--json-out", type=Path, metavar="FILE",
                   help="write the figures (JSON) here; `glpma-fk bench` renders BENCHMARKS.md's Reliability section "
                        "from doc/bench/reliability.json (default: that file after a full run of every section, "
                        "else reliability.json in the log directory)")
    p.add_argument("--from-json", type=Path, metavar="FILE", help="run nothing: print the figures of an earlier run")
    return p


def _usage_error(args) -> str | None:
    """What is wrong with the arguments, or None."""
    for name in ("duration", "phase"):
        v = getattr(args, name)
        if v is not None and not (math.isfinite(v) and v > 0):
            return f"--{name} must be positive"
    for name in ("burst", "deadline_solves"):
        v = getattr(args, name)
        if v is not None and v < 1:
            return f"--{name.replace('_', '-')} must be at least 1"
    if not (math.isfinite(args.rate) and args.rate > 0) or not all(b > 0 for b in args.budgets_ms):
        return "--rate and --budgets-ms must be positive"
    if args.domain is not None and not 0 <= args.domain <= MAX_DOMAIN:
        return f"--domain must be in [0, {MAX_DOMAIN}]"
    if not args.params_file.exists():
        return f"no params file {args.params_file}"
    return None


@command_main
def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    problem = _usage_error(args)
    if problem:
        print(f"error: glpma-fk stress: {problem}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()

    def say(msg):
        print(f"[stress {time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    if args.from_json:
        try:
            res = json.loads(args.from_json.read_text())
        except (OSError, ValueError) as exc:
            print(f"error: glpma-fk stress: cannot read {args.from_json}: {exc}", file=sys.stderr)
            return 2
        print(to_json(res) if args.json else format_table(res))
        return 0 if res.get("passed") else 1
    extra = [a for p in args.params for a in ("-p", p)]
    try:
        res = run(args.sections, args.quick, args.duration, args.rate, args.burst, args.deadline_solves,
                  args.phase, args.params_file, extra, args.domain, args.log_dir, tuple(args.budgets_ms), say)
    except KeyboardInterrupt:
        return 130
    except Exception as exc:  # noqa: BLE001 - one line, not a traceback
        print(f"error: glpma-fk stress: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    res["command"] = shlex.join(["glpma-fk", "stress", *argv])
    log_dir = Path(res.pop("log_dir"))                  # a local directory: not part of the figures
    say(f"the node's output is in {log_dir}")
    full = not args.quick and set(args.sections) == set(SECTIONS)
    path = args.json_out or (RELIABILITY_JSON if full else log_dir / "reliability.json")
    say(f"wrote the figures to {write_json(path, res)}")
    print(to_json(res) if args.json else format_table(res))
    return 0 if res["passed"] else 1
