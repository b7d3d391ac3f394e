"""``glpma-fk``: solve, solve-all, precompile, modes, node, bench, demo, stress, bag, map
(the command line of record: doc/interface.md)."""
from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys

import numpy as np

from . import __version__
from .errors import GlpmaError

EXIT_BAD_INPUT = 2
#: exit status when stdout was closed early (``glpma-fk ... | head -1``): 128 + SIGPIPE, as a shell tool
EXIT_BROKEN_PIPE = 141
#: ``solve`` without ``--budget-ms``: the evaluation cap ends the search; an hour stands for "no clock"
NO_BUDGET_S = 3600.0


class OneLineParser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr and exit status 2."""

    def error(self, message):
        raise SystemExit(_fail(f"{self.prog}: {message}"))


def _fail(message: str) -> int:
    print(f"error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _number(kind, test, what):
    """An argparse type: ``kind`` (int or float) that passes ``test``, else a one-line usage error."""
    def parse(text):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {'an integer' if kind is int else 'a number'}") from None
        if not test(value):
            raise argparse.ArgumentTypeError(f"{text!r} must be {what}")
        return value
    parse.__name__ = kind.__name__      # argparse names the type in "invalid ... value"
    return parse


seed_type = _number(int, lambda v: 0 <= v < 2**63, "a non-negative integer")
count_type = _number(int, lambda v: v >= 1, "at least 1")
positive_float = _number(float, lambda v: math.isfinite(v) and v > 0, "a positive number")


@contextlib.contextmanager
def _one_line_usage_errors():
    """A delegated subcommand's own argparse reports a usage error as one line, exit 2."""
    original = argparse.ArgumentParser.error

    def error(parser, message):
        raise SystemExit(_fail(f"{parser.prog}: {message}"))
    argparse.ArgumentParser.error = error
    try:
        yield
    finally:
        argparse.ArgumentParser.error = original


def _load(config):
    from .config import load_manipulator, resolve_config
    return load_manipulator(resolve_config(config))


def _pose_json(model, x):
    return model.pose(x).as_dict()


def _legs(model, legs):
    """Validated leg lengths (config unit); legs off by a unit factor get a one-line hint."""
    from .config import check_units
    if np.asarray(legs).size == model.n_legs:
        check_units(model, legs)
    return model.check_legs(legs)


def _finite(value):
    """JSON has no inf or NaN: those become null."""
    return float(value) if value is not None and math.isfinite(value) else None


def cmd_solve(args) -> int:
    """One set of leg lengths through the estimator the node uses (cold start, or warm from
    ``--near``), timed after the one-time load of the compiled code (reported as ``load_s``)."""
    from . import precompile
    from .estimator import STATUS_BUDGET, Estimator
    from .solvers import MAX_EVALS
    model = _load(args.config)
    init = {}
    if args.init_range is not None:
        low, high = args.init_range
        if not (np.isfinite(low) and np.isfinite(high) and low < high):
            raise GlpmaError("--init-range needs finite LOW < HIGH")
        init["init_range"] = (low, high)
    near = None if args.near is None else model.check_variables(args.near)
    legs = _legs(model, args.legs)
    budget_s = NO_BUDGET_S if args.budget_ms is None else args.budget_ms / 1e3
    load_s = precompile.exercise(model, args.solver)
    est = Estimator(model, solver=args.solver, time_budget_s=budget_s, tolerance=args.tolerance, seed=args.seed,
                    polish=not args.no_polish, initial_pose=near, max_evals=args.max_evals)
    if init:
        est.set_solver(args.solver, **init)
    e = est.estimate(legs)
    status = e.status
    if status == STATUS_BUDGET and e.elapsed_s < budget_s:
        status = MAX_EVALS          # the searches ended by their evaluation cap, not by the clock
    x = e.x
    out = {"solver": e.solver, "status": status, "fitness": _finite(e.fitness), "evaluations": e.evaluations,
           "elapsed_s": e.elapsed_s, "variables": [] if x is None else [float(v) for v in x],
           "pose": None if x is None else _pose_json(model, x),
           "load_s": load_s, "start": e.start, "conditioning": _finite(e.conditioning), "message": e.message}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{e.solver}: {status} ({e.start} start) after {e.evaluations} evaluations in "
              f"{e.elapsed_s * 1e3:.2f} ms, fitness {e.fitness:.3e}")
        if not e.converged:
            print(f"  {e.message}")
        if x is not None:
            print("  variables: " + ", ".join(f"{n}={v:.9f}" for n, v in zip(model.variable_names, x)))
            p = out["pose"]
            print(f"  position [{model.unit}]: {p['position']}\n  orientation [qx qy qz qw]: {p['orientation']}")
        print(f"  one-time load of the compiled solvers: {load_s:.2f} s (not part of the solve time)")
    return 0 if e.converged else 1


def cmd_solve_all(args) -> int:
    from .solve_all import solve_all
    model = _load(args.config)
    legs = _legs(model, args.legs)
    if args.exact and args.method is not None:
        raise GlpmaError(f"--exact and --method {args.method} exclude each other")
    method = "exact" if args.exact else args.method or ("g3pcx" if args.runs is not None else "multistart")
    if args.runs is not None and method != "g3pcx":
        raise GlpmaError(f"--runs counts G3-PCX searches (--method g3pcx); {method} does not take it")
    if (args.max_starts is not None or args.budget_s is not None) and method != "multistart":
        raise GlpmaError("--max-starts and --budget-s limit --method multistart")
    for name, value, ok in (("--runs", args.runs, lambda v: v >= 1), ("--max-starts", args.max_starts,
                            lambda v: v >= 1), ("--budget-s", args.budget_s, lambda v: v > 0)):
        if value is not None and not ok(value):
            raise GlpmaError(f"{name} must be {'positive' if name == '--budget-s' else 'at least 1'}")
    res = solve_all(model, legs, method=method, runs=args.runs, seed=args.seed, max_starts=args.max_starts,
                    budget_s=args.budget_s)
    extra = {"method": res.method, "evaluations": res.evaluations}
    if res.method == "multistart":
        extra.update(starts=res.starts, stop_reason=res.stop_reason, miss_probability=res.miss_probability,
                     unseen_share_bound=res.unseen_share_bound, hits=list(res.hits))
    if res.method == "exact":
        extra.update(complex_solutions=res.complex_solutions)
    if args.json:
        print(json.dumps({"solutions": [{"variables": [float(v) for v in s.x], "pose": _pose_json(model, s.x),
                                         "fitness": s.fun} for s in res.solutions],
                          "runs": res.runs, "elapsed_s": res.elapsed_s, **extra}))
    else:
        work = {"g3pcx": f"{res.runs} G3-PCX runs", "multistart": f"{res.starts} starts ({res.stop_reason})",
                "exact": f"msolve, {res.complex_solutions} complex solutions"}[res.method]
        print(f"{len(res.solutions)} distinct real assembly modes from {work} in {res.elapsed_s:.3f} s")
        if res.method == "multistart" and res.starts:
            print(f"  chance that one more start finds a new mode (Good-Turing): {res.miss_probability:.3g}; "
                  f"95 % bound on the unseen basins' share: {res.unseen_share_bound:.3g}")
        for line in mode_table(model, res.solutions):
            print(line)
    if not res.solutions:
        print(f"error: no real assembly mode found ({_no_mode_reason(res)})", file=sys.stderr)
        return 1
    return 0


#: width of a number column of the solve-all text output
MODE_COLUMN = 13


def mode_columns(model) -> list:
    """Column names of the solve-all text output: the pose (3-RPR: its solver variables x, y,
    theta; hexapod: position and unit quaternion platform -> base), then the hexapod's solver
    variables (the platform joints B1..B3), then the fitness."""
    unit = model.unit
    if model.kind == "planar_3rpr":
        pose = [f"x [{unit}]", f"y [{unit}]", "theta [rad]"]
        return pose + ["fitness"]
    pose = [f"px [{unit}]", f"py [{unit}]", f"pz [{unit}]", "qx", "qy", "qz", "qw"]
    return pose + [f"{n} [{unit}]" for n in model.variable_names] + ["fitness"]


def mode_table(model, solutions) -> list:
    """The modes as text lines under a header naming each column (:func:`mode_columns`)."""
    names = mode_columns(model)
    lines = ["   #" + "".join(n.rjust(MODE_COLUMN) for n in names)]
    for k, s in enumerate(solutions, 1):
        if model.kind == "planar_3rpr":
            values = list(s.x)
        else:
            p = model.pose(s.x)
            values = [*p.position, *p.orientation, *s.x]
        lines.append(f"  {k:2d}" + "".join(f"{v:{MODE_COLUMN}.6f}" for v in values) + f"{s.fun:{MODE_COLUMN}.2e}")
    return lines


def _no_mode_reason(res) -> str:
    if res.method == "exact":
        return f"certified: none of the {res.complex_solutions} complex solutions is real"
    if res.stop_reason == "unreachable":
        return "the legs cannot reach a common platform position"
    return f"none of {res.runs} {'runs' if res.method == 'g3pcx' else 'starts'} converged; the legs may have no assembly"


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="glpma-fk", description="Forward kinematics of parallel manipulators "
                      "by G3-PCX, RCGA and GLPMA, with a real-time ROS 2 node.")
    p.add_argument("--version", action="version", version=f"glpma-fk {__version__}",
                   help="print the version and exit")
    sub = p.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    _add_solve(sub)
    a = sub.add_parser("solve-all", help="every distinct real assembly mode",
                       description="Every distinct real assembly mode for the given leg lengths, one row each: "
                       "3-RPR x, y [config unit], theta [rad] (the solver variables); hexapod the pose, position "
                       "px py pz [config unit] and unit quaternion qx qy qz qw (platform -> base), beside the "
                       "solver variables x1 .. z3 (the platform joints B1, B2, B3); then the fitness. Exit status 0 "
                       "when at least one is found, 1 when none is (with the reason on stderr), 2 on bad input "
                       "or when --exact cannot run (extra not installed, degenerate geometry).")
    a.add_argument("config", help="manipulator YAML (or the name of a shipped one)")
    a.add_argument("--legs", type=float, nargs="+", required=True, help="leg lengths, config unit")
    a.add_argument("--method", choices=("multistart", "g3pcx"), default=None,
                   help="multistart (default): Levenberg-Marquardt from random poses within the legs' reach, "
                   "stopped when many starts in a row find nothing new; g3pcx: the papers' independent "
                   "polished G3-PCX searches (default when --runs is given)")
    a.add_argument("--exact", action="store_true",
                   help="certified: solve the polynomial system with msolve (pip install 'glpma_ros[exact]'), "
                   "report the number of complex solutions")
    a.add_argument("--max-starts", type=count_type, default=None, help="multistart: cap on the starts (default 20000)")
    a.add_argument("--budget-s", type=float, default=None,
                   help="multistart: wall-clock budget in seconds, checked after each batch of 256 starts "
                   "(stop_reason budget_exhausted when it runs out)")
    a.add_argument("--runs", type=count_type, default=None, help="g3pcx: independent searches (default 200)")
    a.add_argument("--seed", type=seed_type, default=0, help="random seed, a non-negative integer (multistart starts, G3-PCX runs)")
    a.add_argument("--json", action="store_true", help="one JSON object on stdout")
    a.set_defaults(func=cmd_solve_all)
    _add_precompile(sub)
    _add_modes(sub)
    for name, helptext in (("node", "run the estimator node (rclpy or Cyclone DDS)"),
                           ("bench", "reproduce the papers' tables against peers; writes BENCHMARKS.md"),
                           ("demo", "node + mock controller over DDS, live progress, summary and figure"),
                           ("stress", "reliability: overload, burst, restarts, deadlines against a real node"),
                           ("bag", "poses for a recorded rosbag2, offline: pose_estimate, /tf and ~/status added"),
                           ("map", "workspace map: real assembly modes and singularity curves over a 2-D grid")):
        q = sub.add_parser(name, help=helptext, add_help=False)
        q.add_argument("rest", nargs=argparse.REMAINDER)
    return p


def _add_solve(sub) -> None:
    from .solvers import SOLVERS
    s = sub.add_parser("solve", help="solve one set of leg lengths",
                       description="Solve one set of leg lengths with the estimator the node uses: a cold "
                       "start, or a warm start from --near. The time budget counts the solve only; the "
                       "one-time load of the compiled solvers is reported separately (load_s).")
    s.add_argument("config", help="manipulator YAML (or the name of a shipped one)")
    s.add_argument("--legs", type=float, nargs="+", required=True, help="leg lengths, in the config's unit")
    s.add_argument("--solver", choices=list(SOLVERS), default="glpma",
                   help="glpma (default), g3pcx, rcga (the papers'), or the baselines sa, gasa, de")
    s.add_argument("--seed", type=seed_type, default=0, help="random seed, a non-negative integer (default 0)")
    s.add_argument("--budget-ms", type=positive_float, default=None,
                   help="wall-clock budget of the solve in ms (default: none, the evaluation cap ends it)")
    s.add_argument("--max-evals", type=count_type, default=None,
                   help="evaluation cap of each search stage (default: the papers' 10,000 / 500,000)")
    s.add_argument("--tolerance", type=positive_float, default=1e-20,
                   help="fitness (config unit squared) at which the evolutionary search stops; with the "
                        "refinement a pose is converged when its leg residuals are at round-off relative to the "
                        "geometry's size, with --no-polish when its fitness is below this (default 1e-20)")
    s.add_argument("--init-range", type=float, nargs=2, metavar=("LOW", "HIGH"), default=None,
                   help="uniform initial range of every variable of a cold start (default: the papers')")
    s.add_argument("--near", type=float, nargs="+", default=None, metavar="V",
                   help="warm start around these solver variables (3-RPR: x y theta; hexapod: x1 y1 z1 .. z3)")
    s.add_argument("--no-polish", action="store_true",
                   help="the evolutionary solver alone, no Levenberg-Marquardt refinement (the papers' setting)")
    s.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    s.set_defaults(func=cmd_solve)


def _add_precompile(sub) -> None:
    q = sub.add_parser("precompile", help="compile every solver ahead of time (run once after installing)",
                       description="Compile (first run) or load the machine code of every solver for both "
                       "manipulator kinds, so that the first solve and the node's first start do not wait "
                       "for it. One progress line per solver on stderr.")
    q.add_argument("--solvers", nargs="+", metavar="NAME", default=None,
                   help="only these solvers (default: every registered one)")
    q.set_defaults(func=cmd_precompile)


def cmd_precompile(args) -> int:
    from .precompile import precompile
    from .solvers import SOLVERS
    unknown = [n for n in args.solvers or () if n not in SOLVERS]
    if unknown:
        raise GlpmaError(f"unknown solver {unknown[0]!r}; choose among {', '.join(SOLVERS)}")
    precompile(solver_names=args.solvers)
    return 0


def _add_modes(sub) -> None:
    q = sub.add_parser("modes", help="ask a running node for every assembly mode of its last input",
                       description="Publish ~/request_assembly_modes to a running glpma_fk node over "
                       "Cyclone DDS (ROS_DOMAIN_ID, CYCLONEDDS_URI as for the node), wait for its answer on "
                       "~/assembly_modes and print the poses (metres, quaternion x y z w). Exit 1 when no "
                       "node answers or the node reports why it could not.")
    q.add_argument("--node", default="glpma_fk", help="name of the node (default glpma_fk)")
    q.add_argument("--timeout", type=positive_float, default=120.0,
                   help="seconds to wait for the answer (default 120)")
    q.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    q.set_defaults(func=cmd_modes)


def cmd_modes(args) -> int:
    from .node.dds.modes_client import main as modes_main
    return modes_main(args)


def _delegated(command: str):
    """Subcommands with parsers of their own (their options may start with ``--``)."""
    if command == "node":
        from .node.entry import main
    elif command == "bench":
        from glpma_tools.bench import main
    elif command == "demo":
        from glpma_tools.demo import main
    elif command == "stress":
        from glpma_tools.stress import main
    elif command == "bag":
        from glpma_tools.bag import main
    elif command == "map":
        from glpma_tools.workspace_map import main
    else:
        return None
    return main


def _run(argv) -> int:
    delegate = _delegated(argv[0]) if argv else None
    if delegate is not None:
        try:
            with _one_line_usage_errors():
                return int(delegate(argv[1:]) or 0)
        except SystemExit as exc:  # a subcommand's own argparse (--help)
            return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    if args.command != "modes":     # everything else runs the compiled kernels
        from .compat import check_numba
        check_numba()
    return args.func(args)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        code = _run(argv)
        sys.stdout.flush()          # a closed pipe shows here, not at interpreter exit
        return code
    except GlpmaError as exc:
        return _fail(str(exc))
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # the reader went away (| head -1): stop quietly; stdout goes nowhere from now on
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_BROKEN_PIPE


if __name__ == "__main__":
    sys.exit(main())
