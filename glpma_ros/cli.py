"""``glpma-fk``: solve, solve-all, node, bench, demo, stress, bag, map (see CONTRACT.md)."""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from .errors import GlpmaError

EXIT_BAD_INPUT = 2


class OneLineParser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr and exit status 2."""

    def error(self, message):
        raise SystemExit(_fail(f"{self.prog}: {message}"))


def _fail(message: str) -> int:
    print(f"error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _load(config):
    from .config import load_manipulator, resolve_config
    return load_manipulator(resolve_config(config))


def _pose_json(model, x):
    return model.pose(x).as_dict()


def cmd_solve(args) -> int:
    from . import solvers
    model = _load(args.config)
    legs = model.check_legs(args.legs)
    kwargs = {"rng": args.seed, "polish": not args.no_polish, "max_evals": args.max_evals,
              "tolerance": args.tolerance, "budget_s": None if args.budget_ms is None else args.budget_ms / 1e3}
    if args.init_range is not None:
        low, high = args.init_range
        if not (np.isfinite(low) and np.isfinite(high) and low < high):
            raise GlpmaError("--init-range needs finite LOW < HIGH")
        kwargs["init_range"] = (low, high)
    if args.near is not None:
        from .estimator import MIN_SPREAD
        center = model.check_variables(args.near)
        movement = float(np.max(np.abs(legs - model.inverse_kinematics(center))))
        kwargs["center"] = center
        kwargs["spread"] = model.spread_vector(max(movement, MIN_SPREAD * model.scale))
    if args.tolerance is not None and not args.tolerance > 0:
        raise GlpmaError("--tolerance must be positive")
    if args.max_evals is not None and args.max_evals < 1:
        raise GlpmaError("--max-evals must be at least 1")
    if args.budget_ms is not None and not args.budget_ms > 0:
        raise GlpmaError("--budget-ms must be positive")
    r = solvers.solve(args.solver, model, legs, **kwargs)
    out = {"solver": r.solver, "status": r.status, "fitness": r.fun, "evaluations": r.nfev,
           "elapsed_s": r.elapsed_s, "variables": [float(v) for v in r.x], "pose": _pose_json(model, r.x)}
    if args.json:
        print(json.dumps(out))
    else:
        names = model.variable_names
        print(f"{r.solver}: {r.status} after {r.nfev} evaluations in {r.elapsed_s * 1e3:.2f} ms, "
              f"fitness {r.fun:.3e}")
        print("  variables: " + ", ".join(f"{n}={v:.9f}" for n, v in zip(names, r.x)))
        p = out["pose"]
        print(f"  position [{model.unit}]: {p['position']}\n  orientation [qx qy qz qw]: {p['orientation']}")
    return 0 if r.success else 1


def cmd_solve_all(args) -> int:
    from .solve_all import solve_all
    model = _load(args.config)
    legs = model.check_legs(args.legs)
    if args.runs < 1:
        raise GlpmaError("--runs must be at least 1")
    res = solve_all(model, legs, runs=args.runs, seed=args.seed)
    if args.json:
        print(json.dumps({"solutions": [{"variables": [float(v) for v in s.x], "pose": _pose_json(model, s.x),
                                         "fitness": s.fun} for s in res.solutions],
                          "runs": res.runs, "elapsed_s": res.elapsed_s}))
    else:
        print(f"{len(res.solutions)} distinct real assembly modes from {res.runs} runs "
              f"in {res.elapsed_s:.3f} s")
        for k, s in enumerate(res.solutions, 1):
            print(f"  {k:2d}: " + " ".join(f"{v:12.6f}" for v in s.x) + f"   fitness {s.fun:.2e}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="glpma-fk", description="Forward kinematics of parallel manipulators "
                      "by G3-PCX, RCGA and GLPMA, with a real-time ROS 2 node.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    s = sub.add_parser("solve", help="solve one set of leg lengths")
    s.add_argument("config", help="manipulator YAML (or the name of a shipped one)")
    s.add_argument("--legs", type=float, nargs="+", required=True, help="leg lengths, config unit")
    s.add_argument("--solver", choices=list(__import__("glpma_ros.solvers", fromlist=["SOLVERS"]).SOLVERS), default="glpma")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--budget-ms", type=float, default=None, help="wall-clock budget")
    s.add_argument("--max-evals", type=int, default=None, help="evaluation cap (paper's by default)")
    s.add_argument("--tolerance", type=float, default=1e-20, help="fitness threshold of convergence")
    s.add_argument("--init-range", type=float, nargs=2, metavar=("LOW", "HIGH"), default=None)
    s.add_argument("--near", type=float, nargs="+", default=None, help="warm start: solver variables")
    s.add_argument("--no-polish", action="store_true", help="evolutionary solver alone (papers' setting)")
    s.add_argument("--json", action="store_true")
    s.set_defaults(func=cmd_solve)
    a = sub.add_parser("solve-all", help="every distinct real assembly mode")
    a.add_argument("config")
    a.add_argument("--legs", type=float, nargs="+", required=True)
    a.add_argument("--runs", type=int, default=200, help="independent searches")
    a.add_argument("--seed", type=int, default=0)
    a.add_argument("--json", action="store_true")
    a.set_defaults(func=cmd_solve_all)
    for name, helptext in (("node", "run the estimator node (rclpy or Cyclone DDS)"),
                           ("bench", "reproduce the papers' tables against peers; writes BENCHMARKS.md"),
                           ("demo", "node + mock controller over DDS, live progress, summary and figure"),
                           ("stress", "reliability: overload, burst, restarts, deadlines against a real node"),
                           ("bag", "poses for a recorded rosbag2, offline: pose_estimate, /tf and ~/status added"),
                           ("map", "workspace map: real assembly modes and singularity curves over a 2-D grid")):
        q = sub.add_parser(name, help=helptext, add_help=False)
        q.add_argument("rest", nargs=argparse.REMAINDER)
    return p


def _delegated(command: str):
    """Subcommands with parsers of their own (their options may start with ``--``)."""
    if command == "node":
        from .node_entry import main
    elif command == "bench":
        from .bench import main
    elif command == "demo":
        from .demo import main
    elif command == "stress":
        from .stress import main
    elif command == "bag":
        from glpma_tools.bag import main
    elif command == "map":
        from glpma_tools.workspace_map import main
    else:
        return None
    return main


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        delegate = _delegated(argv[0]) if argv else None
        if delegate is not None:
            try:
                return int(delegate(argv[1:]) or 0)
            except SystemExit as exc:  # a subcommand's own argparse (--help, usage error)
                return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:
            return int(exc.code or 0)
        return args.func(args)
    except GlpmaError as exc:
        return _fail(str(exc))
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
