"""``glpma-fk``: solve, solve-all, precompile, modes, node, and the installed tools' subcommands
(the command line of record: doc/interface.md).

The tools (:mod:`glpma_tools`: bench, demo, stress, bag, map, ...) plug their subcommands in through
the entry-point group :data:`COMMANDS` (as ros2cli's verbs do): one line in setup.py,
``"NAME = module:main [extra]"``, where ``main(argv) -> exit status`` parses its own arguments,
the first line of ``module``'s docstring (``glpma-fk NAME: what it does``) is its line in
``glpma-fk --help``, and ``extra`` is the setup.py extra it needs.  This module imports none of
them: ``--help`` reads the docstrings without importing the modules, and an installation
without the extra lists the command with the pip command that installs it."""
from __future__ import annotations

import argparse
import ast
import functools
import importlib.machinery
import importlib.metadata
import importlib.util
import json
import math
import os
import re
import sys

import numpy as np

from .. import __version__
from ..errors import GlpmaError

EXIT_BAD_INPUT = 2
#: exit status when stdout was closed early (``glpma-fk ... | head -1``): 128 + SIGPIPE, as a shell tool
EXIT_BROKEN_PIPE = 141
#: ``solve`` without ``--budget-ms``: the evaluation cap ends the search; an hour stands for "no clock"
NO_BUDGET_S = 3600.0


#: the entry-point group of glpma-fk's plug-in subcommands (see the module's docstring)
COMMANDS = "glpma_fk.commands"
#: the distribution whose extras the plug-ins name
DISTRIBUTION = "glpma_ros"


class OneLineParser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr and exit status 2."""

    def error(self, message):
        raise SystemExit(_fail(f"{self.prog}: {message}"))


def _fail(message: str) -> int:
    print(f"error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def command_main(main):
    """Decorator of a command's ``main(argv) -> exit status``, the one place where its outcomes
    become exit statuses: argparse's exit (``--help``: 0; a :class:`OneLineParser` usage error,
    already printed: 2), a :class:`~glpma_ros.errors.GlpmaError` (one line on stderr, 2) and
    Ctrl-C (130)."""
    @functools.wraps(main)
    def run(argv=None) -> int:
        try:
            return int(main(argv) or 0)
        except SystemExit as exc:
            return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else _fail(str(exc.code)))
        except GlpmaError as exc:
            return _fail(str(exc))
        except KeyboardInterrupt:
            return 130
    return run


# -- plug-in subcommands ------------------------------------------------------------------------
def plugins() -> dict:
    """name -> ``importlib.metadata.EntryPoint`` of every installed plug-in subcommand."""
    return {ep.name: ep for ep in importlib.metadata.entry_points(group=COMMANDS)}


def missing_requirements(extra: str) -> list[str]:
    """The distributions the setup.py ``extra`` requires that are not installed."""
    try:
        requires = importlib.metadata.requires(DISTRIBUTION) or []
    except importlib.metadata.PackageNotFoundError:
        return []
    marker = re.compile(rf"""extra\s*==\s*["']{re.escape(extra)}["']""")
    missing = []
    for requirement in requires:
        name = re.match(r"[A-Za-z0-9._-]+", requirement).group(0)
        if marker.search(requirement) and name not in missing:
            try:
                importlib.metadata.version(name)
            except importlib.metadata.PackageNotFoundError:
                missing.append(name)
    return missing


def _missing_extra(ep) -> tuple[str, list] | None:
    """``(extra, its distributions not installed)`` of plug-in ``ep``, or None when it can run here."""
    for extra in ep.extras:
        missing = missing_requirements(extra)
        if missing:
            return extra, missing
    return None


def _summary(ep) -> str:
    """The first line of the plug-in's module docstring, read without importing the module."""
    try:
        top, *parts = ep.module.split(".")
        spec = importlib.util.find_spec(top)          # a top-level name is found, not imported
        for part in parts:                            # nor are the packages on the way down
            spec = importlib.machinery.PathFinder.find_spec(part, spec.submodule_search_locations)
        with open(spec.origin, encoding="utf-8") as f:
            doc = ast.get_docstring(ast.parse(f.read())) or ""
    except (ImportError, AttributeError, TypeError, OSError, SyntaxError):
        return ""
    line = doc.strip().splitlines()[0] if doc.strip() else ""
    return re.sub(r"^``[^`]*``:\s*|^glpma-fk \S+:\s*", "", line).replace("``", "").rstrip(".")


def _run_plugin(ep, argv) -> int:
    missing = _missing_extra(ep)
    if missing is not None:
        extra, names = missing
        return _fail(f"glpma-fk {ep.name} needs {', '.join(names)}: pip install '{DISTRIBUTION}[{extra}]' "
                     f"(in a checkout: pip install -e '.[{extra}]')")
    return int(ep.load()(argv) or 0)


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


def _load(config):
    from ..config import load_manipulator, resolve_config
    return load_manipulator(resolve_config(config))


def _pose_json(model, x):
    return model.pose(x).as_dict()


def _legs(model, legs):
    """Validated leg lengths (config unit) from the sensors' readings ``legs`` (the config's
    ``leg_offsets`` added); legs off by a unit factor get a one-line hint."""
    from ..config import check_units
    if np.asarray(legs).size == model.n_legs:
        check_units(model, legs)
    return model.check_legs(model.legs_from_sensors(legs))


def _finite(value):
    """JSON has no inf or NaN: those become null."""
    return float(value) if value is not None and math.isfinite(value) else None


def cmd_solve(args) -> int:
    """One set of leg lengths through the estimator the node uses (cold start, or warm from
    ``--near``), timed after the one-time load of the compiled code (reported as ``load_s``)."""
    from ..estimation.estimator import STATUS_BUDGET, Estimator
    from ..runtime import precompile
    from ..solvers import MAX_EVALS
    model = _load(args.config)
    if args.init_range is not None:
        low, high = args.init_range
        if not (np.isfinite(low) and np.isfinite(high) and low < high):
            raise GlpmaError("--init-range needs finite LOW < HIGH")
    near = None if args.near is None else model.check_variables(args.near)
    legs = _legs(model, args.legs)
    budget_s = NO_BUDGET_S if args.budget_ms is None else args.budget_ms / 1e3
    load_s = precompile.exercise(model, args.solver)
    est = Estimator(model, solver=args.solver, time_budget_s=budget_s, tolerance=args.tolerance, seed=args.seed,
                    polish=not args.no_polish, initial_pose=near, max_evals=args.max_evals,
                    init_range=args.init_range, leg_noise_std=args.leg_noise_std)
    e = est.estimate(legs)
    status = e.status
    if status == STATUS_BUDGET and e.elapsed_s < budget_s:
        status = MAX_EVALS          # the searches ended by their evaluation cap, not by the clock
    x = e.x
    out = {"solver": e.solver, "status": status, "fitness": _finite(e.fitness), "evaluations": e.evaluations,
           "elapsed_s": e.elapsed_s, "variables": [] if x is None else [float(v) for v in x],
           "pose": None if x is None else _pose_json(model, x),
           "load_s": load_s, "start": e.start, "conditioning": _finite(e.conditioning), "message": e.message}
    if model.redundancy:            # legs numbered from 1, as in the messages
        out.update(consistency=_finite(e.consistency), consistency_limit=_finite(e.consistency_limit),
                   suspect_leg=None if e.suspect_leg is None else e.suspect_leg + 1,
                   excluded_leg=None if e.excluded_leg is None else e.excluded_leg + 1,
                   leg_noise_std=est.leg_noise_std)
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{e.solver}: {status} ({e.start} start) after {e.evaluations} evaluations in "
              f"{e.elapsed_s * 1e3:.2f} ms, fitness {e.fitness:.3e}")
        if not e.converged or model.redundancy:
            print(f"  {e.message}")
        if x is not None:
            print("  variables: " + ", ".join(f"{n}={v:.9f}" for n, v in zip(model.variable_names, x)))
            p = out["pose"]
            print(f"  position [{model.unit}]: {p['position']}\n  orientation [qx qy qz qw]: {p['orientation']}")
        print(f"  one-time load of the compiled solvers: {load_s:.2f} s (not part of the solve time)")
    return 0 if e.publishable else 1


def cmd_solve_all(args) -> int:
    """Every real assembly mode; the one-time load of the compiled code is done first and reported
    apart (``load_s``), so that ``elapsed_s`` is the search alone."""
    from ..modes.multistart import solve_all
    from ..runtime import precompile
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
    # the compiled code of the method that runs (msolve is a separate program: nothing to load)
    load_s = 0.0 if method == "exact" else precompile.exercise_solve_all(model, methods=(method,))
    res = solve_all(model, legs, method=method, runs=args.runs, seed=args.seed, max_starts=args.max_starts,
                    budget_s=args.budget_s, leg_noise_std=args.leg_noise_std)
    extra = {"method": res.method, "evaluations": res.evaluations, "load_s": load_s}
    if res.method == "multistart":
        extra.update(starts=res.starts, stop_reason=res.stop_reason, miss_probability=res.miss_probability,
                     unseen_share_bound=res.unseen_share_bound, hits=list(res.hits),
                     partner_starts=res.partner_starts, parity_starts=res.parity_starts,
                     conditioning=list(res.conditioning), double_modes=res.double_modes)
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
        if load_s:
            print(f"  one-time load of the compiled solvers: {load_s:.2f} s (not part of the search time)")
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
    a.add_argument("--leg-noise-std", type=positive_float, default=None,
                   help="redundant legs: standard deviation of the leg measurements in the config's unit; a mode "
                        "is a least-squares pose whose residuals pass the chi-square test against it (default: "
                        "1e-5 m, the node's leg_noise_std)")
    a.add_argument("--seed", type=seed_type, default=0, help="random seed, a non-negative integer (multistart starts, G3-PCX runs)")
    a.add_argument("--json", action="store_true", help="one JSON object on stdout")
    a.set_defaults(func=cmd_solve_all)
    _add_precompile(sub)
    _add_modes(sub)
    _add_urdf(sub)
    # subcommands with parsers of their own (their options may start with ``--``)
    delegated = {"node": "run the estimator node (rclpy or Cyclone DDS)"}
    for name, ep in sorted(plugins().items()):
        missing = _missing_extra(ep)
        delegated.setdefault(name, _summary(ep) + (f" (not installed: pip install '{DISTRIBUTION}[{missing[0]}]')"
                                                   if missing else ""))
    for name, helptext in delegated.items():
        q = sub.add_parser(name, help=helptext, add_help=False)
        q.add_argument("rest", nargs=argparse.REMAINDER)
    return p


def _add_solve(sub) -> None:
    from ..solvers import SOLVERS
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
    s.add_argument("--leg-noise-std", type=positive_float, default=None,
                   help="redundant legs: standard deviation of the leg measurements in the config's unit, for the "
                        "chi-square consistency test (default: 1e-5 m, the node's leg_noise_std)")
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
    from ..runtime.precompile import precompile
    from ..solvers import SOLVERS
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
    from ..node.dds.modes_client import main as modes_main
    return modes_main(args)


def _add_urdf(sub) -> None:
    q = sub.add_parser("urdf", help="the manipulator's URDF (loop-cut tree) for robot_state_publisher and RViz",
                       description="Write the URDF of the manipulator of CONFIG (plain URDF, no xacro; metres, "
                       "radians): base_link, each leg a chain of its joints as built (hexapod: universal joint "
                       "legI_u1, legI_u2, prismatic legI_actuator, spherical joint legI_s1, legI_s2, legI_s3; "
                       "3-RPR: legI_base, legI_actuator, legI_platform) ending at its platform joint (link "
                       "legI_end), platform_link fixed to leg1_end (the loop cut). The glpma_fk node publishes "
                       "every joint's state on ~/mechanism_joint_states (publish_joint_states:=true). Joint naming: "
                       "doc/interface.md.")
    q.add_argument("config", help="manipulator YAML (or the name of a shipped one)")
    q.add_argument("--out", default=None, metavar="FILE", help="write the URDF here (default: stdout)")
    q.add_argument("--prefix", default="", metavar="NAME_",
                   help="put before every link, joint and material name (e.g. left_), for two robots in one tree")
    q.add_argument("--meshes", default=None, metavar="DIR",
                   help="a folder of meshes (metres, in their link's frame): a link named LINK (without the prefix) "
                        "shows DIR/LINK.stl (or .dae, .obj) where it exists, a leg's link also DIR/leg_PART.stl "
                        "(e.g. leg_cylinder.stl, leg_rod.stl for every leg); the other links keep the simple geometry")
    q.add_argument("--name", default=None, help="the robot's name (default: the config's file name)")
    q.set_defaults(func=cmd_urdf)


def cmd_urdf(args) -> int:
    from pathlib import Path

    from ..config import resolve_config
    from ..description.urdf import urdf_text
    from ..node.params import URDF_PREFIX
    if not URDF_PREFIX.fullmatch(args.prefix):
        raise GlpmaError(f"--prefix {args.prefix!r}: use letters, digits, '_' and '/' only")
    if args.meshes is not None and not Path(args.meshes).expanduser().is_dir():
        raise GlpmaError(f"--meshes {args.meshes}: not a folder")
    path = resolve_config(args.config)
    model = _load(args.config)
    name = args.name or Path(str(path)).stem
    text = urdf_text(model, robot_name=name, prefix=args.prefix, meshes=args.meshes, source=Path(str(path)).name,
                     passive_limits=getattr(model, "passive_limits", None))
    if args.out is None:
        sys.stdout.write(text)
        return 0
    out = Path(args.out)
    if out.resolve() == Path(str(path)).resolve():
        raise GlpmaError(f"--out {args.out} is the config itself; an input file is never overwritten")
    try:
        out.write_text(text)
    except OSError as exc:
        raise GlpmaError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    print(f"wrote {out} ({model.n_legs} legs)", file=sys.stderr)
    return 0


def _run(argv) -> int:
    if argv and argv[0] == "node":
        from ..node.entry import main as node_main
        return node_main(argv[1:])
    plugin = plugins().get(argv[0]) if argv else None
    if plugin is not None:
        return _run_plugin(plugin, argv[1:])
    args = build_parser().parse_args(argv)
    if args.command not in ("modes", "urdf"):     # everything else runs the compiled kernels
        from ..runtime.compat import check_numba
        check_numba()
    return args.func(args)


@command_main
def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        code = _run(argv)
        sys.stdout.flush()          # a closed pipe shows here, not at interpreter exit
        return code
    except BrokenPipeError:
        # the reader went away (| head -1): stop quietly; stdout goes nowhere from now on
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_BROKEN_PIPE


if __name__ == "__main__":
    sys.exit(main())
