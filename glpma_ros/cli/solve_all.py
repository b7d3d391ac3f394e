"""``glpma-fk solve-all``: every distinct real assembly mode of one set of leg lengths."""
from __future__ import annotations

import json
import sys

from ..errors import GlpmaError
from ..modes.multistart import default_method, has_closed_form, solve_all
from ..runtime import precompile
from ..runtime.compat import check_numba
from .api import OneLineParser, command_main, count_type, manipulator_parser, positive_float, seed_type
from .inputs import load, pose_json, sensor_legs

#: the command's --help text
DESCRIPTION = ("Every distinct real assembly mode for the given leg lengths, one row each: 3-RPR x, y [config unit], "
               "theta [rad] (the solver variables); hexapod the pose, position px py pz [config unit] and unit "
               "quaternion qx qy qz qw (platform -> base), beside the solver variables x1 .. z3 (the platform joints "
               "B1, B2, B3); then the fitness. Exit status 0 when at least one is found, 1 when none is (with the "
               "reason on stderr), 2 on bad input or when --exact cannot run (extra not installed, degenerate "
               "geometry).")


def build_parser() -> OneLineParser:
    a = manipulator_parser("glpma-fk solve-all", DESCRIPTION, legs=True)
    a.add_argument("--method", choices=("homotopy", "multistart", "g3pcx", "closed_form"), default=None,
                   help="closed_form: the Delta's sphere intersection (its default); "
                   "homotopy (default for the 3-RPR and the hexapods): a compiled parameter homotopy, one "
                   "path per complex solution of a generic member, complete when the distinct endpoints are "
                   "as many as the root count (JSON complete, paths, paths_failed, complex_solutions, "
                   "real_solutions); multistart (the default otherwise and when --max-starts or --budget-s is "
                   "given): Levenberg-Marquardt from random poses within the legs' reach, "
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
    a.add_argument("--threads", type=count_type, default=None, metavar="N",
                   help="homotopy: threads tracking its paths, which are independent (default: the cores this "
                   "process may run on, one per 8 paths at most; the modes do not depend on it)")
    a.add_argument("--seed", type=seed_type, default=0,
                   help="random seed, a non-negative integer (homotopy gamma, multistart starts, G3-PCX runs)")
    a.add_argument("--json", action="store_true", help="one JSON object on stdout")
    return a


def run(args) -> int:
    """Every real assembly mode; the one-time load of the compiled code is done first and reported
    apart (``load_s``), so that ``elapsed_s`` is the search alone."""
    model = load(args.config)
    legs = sensor_legs(model, args.legs)
    if args.exact and args.method is not None:
        raise GlpmaError(f"--exact and --method {args.method} exclude each other")
    if args.exact:
        method = "exact"
    elif args.method is not None:
        method = args.method
    elif args.runs is not None:
        method = "g3pcx"
    elif args.max_starts is not None or args.budget_s is not None:
        method = "multistart"
    else:
        method = default_method(model)
    if method == "closed_form" and not has_closed_form(model):
        raise GlpmaError(f"{model.kind} has no closed-form forward kinematics; use --method multistart")
    if args.runs is not None and method != "g3pcx":
        raise GlpmaError(f"--runs counts G3-PCX searches (--method g3pcx); {method} does not take it")
    if (args.max_starts is not None or args.budget_s is not None) and method != "multistart":
        raise GlpmaError("--max-starts and --budget-s limit --method multistart")
    if args.threads is not None and method != "homotopy":
        raise GlpmaError(f"--threads counts the homotopy's path-tracking threads; {method} does not take it")
    for name, value, ok in (("--runs", args.runs, lambda v: v >= 1), ("--max-starts", args.max_starts,
                            lambda v: v >= 1), ("--budget-s", args.budget_s, lambda v: v > 0)):
        if value is not None and not ok(value):
            raise GlpmaError(f"{name} must be {'positive' if name == '--budget-s' else 'at least 1'}")
    # the compiled code of the method that runs (msolve is a separate program: nothing to load)
    load_s = 0.0 if method in ("exact", "closed_form") else precompile.exercise_solve_all(model, methods=(method,))
    res = solve_all(model, legs, method=method, runs=args.runs, seed=args.seed, max_starts=args.max_starts,
                    budget_s=args.budget_s, leg_noise_std=args.leg_noise_std, threads=args.threads)
    extra = {"method": res.method, "evaluations": res.evaluations, "load_s": load_s}
    if res.method == "multistart":
        extra.update(starts=res.starts, stop_reason=res.stop_reason, miss_probability=res.miss_probability,
                     good_turing=res.good_turing, unseen_share_bound=res.unseen_share_bound, hits=list(res.hits),
                     partner_starts=res.partner_starts, parity_starts=res.parity_starts,
                     conditioning=list(res.conditioning), double_modes=res.double_modes)
    if res.method == "exact":
        extra.update(complex_solutions=res.complex_solutions, complete=True, real_solutions=res.real_solutions)
    if res.method == "homotopy":
        extra.update(complete=res.complete, paths=res.paths, paths_failed=list(res.paths_failed),
                     complex_solutions=res.complex_solutions, real_solutions=res.real_solutions,
                     fallback=res.fallback or None, retracked=res.retracked, steps=res.steps)
    if args.json:
        print(json.dumps({"solutions": [{"variables": [float(v) for v in s.x], "pose": pose_json(model, s.x),
                                         "fitness": s.fun} for s in res.solutions],
                          "runs": res.runs, "elapsed_s": res.elapsed_s, **extra}))
    else:
        work = {"g3pcx": f"{res.runs} G3-PCX runs", "multistart": f"{res.starts} starts ({res.stop_reason})",
                "exact": f"msolve, {res.complex_solutions} complex solutions",
                "closed_form": "the closed form",
                "homotopy": f"{res.paths} homotopy paths, {res.complex_solutions} complex solutions"}[res.method]
        print(f"{len(res.solutions)} distinct real assembly modes from {work} in {res.elapsed_s:.3f} s")
        if res.method == "homotopy":
            print("  complete: every solution found (certified by the root count)" if res.complete and not res.fallback
                  else "  complete: by msolve, after the homotopy fell short" if res.complete
                  else f"  NOT complete: {res.complex_solutions} of {res.paths} solutions found; paths without "
                       f"their own: {', '.join(map(str, res.paths_failed)) or 'none'} (install the exact extra "
                       "for msolve's certified count)")
        if res.method == "multistart" and res.starts:
            print(f"  not certified: a mode whose basin holds too few of the starts is missed unseen (use the "
                  f"homotopy or --exact); chance that the next start finds a new mode (Good-Turing): "
                  f"{res.good_turing:.3g}; 95 % bound on the unseen basins' share: {res.unseen_share_bound:.3g}")
        if load_s:
            print(f"  one-time load of the compiled solvers: {load_s:.2f} s (not part of the search time)")
        for line in mode_table(model, res.solutions):
            print(line)
    if not res.solutions:
        print(f"error: no real assembly mode found ({no_mode_reason(res)})", file=sys.stderr)
        return 1
    return 0


#: width of a number column of the solve-all text output
MODE_COLUMN = 13


def mode_columns(model) -> list:
    """Column names of the solve-all text output: the pose (3-RPR: its solver variables x, y,
    theta; hexapod: position and unit quaternion platform -> base), then the hexapod's solver
    variables (the platform joints B1..B3), then the fitness."""
    unit = model.unit
    if model.variable_names == ("x", "y", "z"):      # a platform that only translates (deltas)
        return [f"px [{unit}]", f"py [{unit}]", f"pz [{unit}]", "fitness"]
    if model.variable_names == ("x", "y", "theta"):      # planar: 3-RPR, 3-RRR
        pose = [f"x [{unit}]", f"y [{unit}]", "theta [rad]"]
        return pose + ["fitness"]
    pose = [f"px [{unit}]", f"py [{unit}]", f"pz [{unit}]", "qx", "qy", "qz", "qw"]
    return pose + [f"{n} [{unit}]" for n in model.variable_names] + ["fitness"]


def mode_table(model, solutions) -> list:
    """The modes as text lines under a header naming each column (:func:`mode_columns`)."""
    names = mode_columns(model)
    lines = ["   #" + "".join(n.rjust(MODE_COLUMN) for n in names)]
    for k, s in enumerate(solutions, 1):
        if model.variable_names in (("x", "y", "theta"), ("x", "y", "z")):
            values = list(s.x)
        else:
            p = model.pose(s.x)
            values = [*p.position, *p.orientation, *s.x]
        lines.append(f"  {k:2d}" + "".join(f"{v:{MODE_COLUMN}.6f}" for v in values) + f"{s.fun:{MODE_COLUMN}.2e}")
    return lines


def no_mode_reason(res) -> str:
    if res.method == "exact" or (res.method == "homotopy" and res.complete):
        return f"certified: none of the {res.complex_solutions} complex solutions is real"
    if res.method == "homotopy":
        return (f"none of the {res.complex_solutions} complex solutions found is real, and the homotopy is not "
                "complete")
    if res.stop_reason == "unreachable":
        return "the legs cannot reach a common platform position"
    what = "runs" if res.method == "g3pcx" else "starts"
    return f"none of {res.runs} {what} converged; the legs may have no assembly"


@command_main
def main(argv=None) -> int:
    check_numba()
    return run(build_parser().parse_args(argv))
