"""``glpma-fk solve``: one set of leg lengths through the estimator the node uses."""
from __future__ import annotations

import json

import numpy as np

from ..errors import GlpmaError
from ..estimation.estimator import Estimator
from ..runtime import precompile
from ..runtime.compat import check_numba
from ..solvers import SOLVERS
from .api import OneLineParser, command_main, count_type, manipulator_parser, positive_float, seed_type
from .inputs import finite, load, pose_json, sensor_legs

#: ``solve`` without ``--budget-ms``: the evaluation cap ends the search; an hour stands for "no clock"
NO_BUDGET_S = 3600.0


#: the command's --help text
DESCRIPTION = ("Solve one set of leg lengths with the estimator the node uses: a cold start, or a warm start from "
               "--near. The time budget counts the solve only; the one-time load of the compiled solvers is reported "
               "separately (load_s).")


def build_parser() -> OneLineParser:
    s = manipulator_parser("glpma-fk solve", DESCRIPTION, legs=True)
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
    return s


def run(args) -> int:
    """One set of leg lengths through the estimator the node uses (cold start, or warm from
    ``--near``), timed after the one-time load of the compiled code (reported as ``load_s``)."""
    model = load(args.config)
    if args.init_range is not None:
        low, high = args.init_range
        if not (np.isfinite(low) and np.isfinite(high) and low < high):
            raise GlpmaError("--init-range needs finite LOW < HIGH")
    near = None if args.near is None else model.check_variables(args.near)
    legs = sensor_legs(model, args.legs)
    budget_s = NO_BUDGET_S if args.budget_ms is None else args.budget_ms / 1e3
    load_s = precompile.exercise(model, args.solver)
    est = Estimator(model, solver=args.solver, time_budget_s=budget_s, tolerance=args.tolerance, seed=args.seed,
                    polish=not args.no_polish, initial_pose=near, max_evals=args.max_evals,
                    init_range=args.init_range, leg_noise_std=args.leg_noise_std)
    e = est.estimate(legs)
    status = e.status               # budget_exhausted / max_evals: the limit that stopped the search
    x = e.x
    out = {"solver": e.solver, "status": status, "fitness": finite(e.fitness), "evaluations": e.evaluations,
           "elapsed_s": e.elapsed_s, "variables": [] if x is None else [float(v) for v in x],
           "pose": None if x is None else pose_json(model, x),
           "load_s": load_s, "start": e.start, "conditioning": finite(e.conditioning), "message": e.message}
    if model.redundancy:            # legs numbered from 1, as in the messages
        out.update(consistency=finite(e.consistency), consistency_limit=finite(e.consistency_limit),
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


@command_main
def main(argv=None) -> int:
    check_numba()
    return run(build_parser().parse_args(argv))
