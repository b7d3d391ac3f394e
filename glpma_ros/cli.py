"""``glpma-fk``: solve, solve-all, node, bench, demo (see CONTRACT.md)."""
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
        for k, s in enumerate(res.solutions, 1):
            print(f"  {k:2d}: " + " ".join(f"{v:12.6f}" for v in s.x) + f"   fitness {s.fun:.2e}")
    if not res.solutions:
        print(f"error: no real assembly mode found ({_no_mode_reason(res)})", file=sys.stderr)
        return 1
    return 0


def _no_mode_reason(res) -> str:
    if res.method == "exact":
        return f"certified: none of the {res.complex_solutions} complex solutions is real"
    if res.stop_reason == "unreachable":
        return "the legs cannot reach a common platform position"
    return f"none of {res.runs} {'runs' if res.method == 'g3pcx' else 'starts'} converged; the legs may have no assembly"


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
    a = sub.add_parser("solve-all", help="every distinct real assembly mode",
                       description="Every distinct real assembly mode for the given leg lengths. Exit status 0 "
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
    a.add_argument("--max-starts", type=int, default=None, help="multistart: cap on the starts (default 20000)")
    a.add_argument("--budget-s", type=float, default=None,
                   help="multistart: wall-clock budget in seconds (stop_reason budget_exhausted when it runs out)")
    a.add_argument("--runs", type=int, default=None, help="g3pcx: independent searches (default 200)")
    a.add_argument("--seed", type=int, default=0, help="random seed (multistart starts, G3-PCX runs)")
    a.add_argument("--json", action="store_true", help="one JSON object on stdout")
    a.set_defaults(func=cmd_solve_all)
    for name, helptext in (("node", "run the estimator node (rclpy or Cyclone DDS)"),
                           ("bench", "reproduce the papers' tables against peers; writes BENCHMARKS.md"),
                           ("demo", "node + mock controller over DDS, live progress, summary and figure"),
                           ("stress", "reliability: overload, burst, restarts, deadlines against a real node")):
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
