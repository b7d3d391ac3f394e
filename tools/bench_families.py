"""Figures for BENCHMARKS.md: every manipulator family in one run -- the leg-length ones (3-RPR, 6-6 hexapod)
beside the actuated families (rotary Delta, 6-RUS, 3-RRR and any other shipped family config).

    .venv/bin/python tools/bench_families.py [--steps N] [--cold N] [--seed N] [--markdown PATH]

``--markdown doc/bench/families.md`` keeps the section in BENCHMARKS.md: ``glpma-fk bench`` appends that file
when it rewrites the report (``glpma_tools.bench.report.APART``).

Per family, on its shipped config:

* **warm**: ``Estimator.estimate`` along one loop of the demo's trajectory (``--steps`` inputs, exact inverse
  kinematics), warm from the previous estimate, timed per call (the solve only; wall clock, with the share of
  calls another process preempted), and the largest distance to the true pose; beside it, just before the warm
  loop, the median time of a fixed piece of interpreter and small-array work (:func:`reference_work`): on a
  shared virtual machine the speed of such code changes by up to 1.8x from one second to the next (when the
  host's other tenants compete for the core's caches and units) while a compiled arithmetic loop's does not, and
  the reference tells a slow stretch from a slow solve;
* **cold**: ``--cold`` inputs at random points of that loop, each solved by a new ``Estimator`` (no previous
  pose: the closed form where the family has one, else the default solver from its cold range) under the node's
  default budget; the share converged, the evaluations, the time;
* **solve-all**: ``solve_all`` with the family's default method at the loop's start (the Delta's closed form,
  the homotopy of the leg-length models, else the multistart): real modes, and the median time of
  ``SOLVE_ALL_CALLS`` calls after one untimed call (a process's first call loads the compiled code: seconds).

Prints Markdown (and writes it to ``--markdown``).
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import yaml

from glpma_ros.config import config_dir, load_document, model_from_dict
from glpma_ros.estimation.estimator import STATUS_CONVERGED, Estimator
from glpma_ros.models.families import is_family
from glpma_ros.models.rotations import quaternion_from_matrix
from glpma_ros.modes.multistart import default_method, solve_all
from glpma_tools.sim.trajectories import start_pose, variables_along
from glpma_tools.timing import emit_report, git_revision, measured_run, timed_calls, warm_up

#: the leg-length models, measured in the same run as the families
LEG_LENGTH_CONFIGS = (("3-RPR", "planar_3rpr_seed.yaml"), ("6-6 hexapod", "hexapod_66_rolland.yaml"))
#: the node's default time budget (ms): the cold solves' budget, as the node gives them
BUDGET_MS = 2.0
#: warm-up calls before the timed warm loop (Numba's first calls compile or load)
WARM_UP_CALLS = 19
#: timed solve_all calls (after one untimed call that loads the compiled code), reported by their median
SOLVE_ALL_CALLS = 3
#: calls of the machine-speed reference before each warm loop (reported by their median)
REFERENCE_CALLS = 2000


#: the reference's input: the same for every family (a 6-leg reading's size)
REFERENCE_ROW = np.linspace(1.0, 2.0, 6)


def reference_work(row):
    """A fixed piece of interpreter and small-array work -- a copy, an allocation, a list -- like the Python share
    of a warm solve: its time follows the machine's speed for that kind of code."""
    a = np.array(row, dtype=float)
    b = np.empty(2 * a.shape[0])
    b[:a.shape[0]] = a
    return b.tolist()


def reference_us() -> float:
    """Median time (µs) of :func:`reference_work` on :data:`REFERENCE_ROW` over :data:`REFERENCE_CALLS` calls."""
    times = np.empty(REFERENCE_CALLS)
    for i in range(REFERENCE_CALLS):
        t0 = time.perf_counter()
        reference_work(REFERENCE_ROW)
        times[i] = time.perf_counter() - t0
    return 1e6 * float(np.median(times))


def family_configs() -> list:
    """(label, file) of every shipped actuated-family config, by name."""
    out = []
    for path in sorted(config_dir().glob("*.yaml")):
        doc = yaml.safe_load(path.read_text())
        if is_family(doc):
            out.append((f"{doc['manipulator']} ({path.stem})", path.name))
    return out


def measure(name: str, steps: int, cold: int, rng) -> dict:
    path = config_dir() / name
    doc = load_document(path)
    model = model_from_dict(doc, str(path))
    p0, R0 = start_pose(model, doc)
    xs = variables_along(model, model.variables_from_pose(p0, quaternion_from_matrix(R0)), steps + 1)
    legs = np.array([model.inverse_kinematics(x) for x in xs])
    spare = Estimator(model, initial_pose=xs[0], time_budget_s=BUDGET_MS / 1e3)
    warm_up(lambda i: spare.estimate(legs[1 + i % WARM_UP_CALLS]), BUDGET_MS)
    est = Estimator(model, initial_pose=xs[0], time_budget_s=BUDGET_MS / 1e3)
    reference = reference_us()
    calls = timed_calls(lambda i: est.estimate(legs[i + 1]), steps, BUDGET_MS, stop_early=False)
    us = calls.elapsed_s * 1e6
    warm_ok = sum(e.status == STATUS_CONVERGED for e in calls.results)
    err = max(model.distance(e.x, x) for e, x in zip(calls.results, xs[1:]) if e.x is not None)
    picks = rng.choice(len(xs), size=cold, replace=cold > len(xs))
    cold_ok, cold_evals, cold_s, cold_other = 0, [], [], {}
    for k, i in enumerate(picks):
        e0 = Estimator(model, seed=int(k), time_budget_s=BUDGET_MS / 1e3)
        t0 = time.perf_counter()
        e = e0.estimate(legs[i])
        cold_s.append(time.perf_counter() - t0)
        cold_ok += e.status == STATUS_CONVERGED
        if e.status != STATUS_CONVERGED:
            cold_other[e.status] = cold_other.get(e.status, 0) + 1
        cold_evals.append(e.evaluations)
    method = default_method(model)
    solve_all(model, legs[0], method=method, seed=0)             # loads (or compiles) its code: not timed
    all_times = []
    for _ in range(SOLVE_ALL_CALLS):
        t0 = time.perf_counter()
        modes = solve_all(model, legs[0], method=method, seed=0)
        all_times.append(time.perf_counter() - t0)
    all_s = float(np.median(all_times))
    calm = us[~calls.preempted] if np.any(~calls.preempted) else us
    return {"legs": model.n_legs, "p50": np.percentile(us, 50), "reference": reference,
            "p99": np.percentile(us, 99), "max": us.max(),
            "p99_calm": np.percentile(calm, 99), "cold_other": cold_other,
            "preempted": 100.0 * calls.preempted.mean(), "warm_ok": warm_ok, "steps": steps,
            "error_rel": err / model.scale, "cold": cold, "cold_ok": cold_ok,
            "cold_evals": float(np.mean(cold_evals)), "cold_p50_ms": 1e3 * float(np.median(cold_s)),
            "method": method, "modes": len(modes.solutions), "all_s": all_s}


def report(rows, args, conditions) -> str:
    lines = ["## Every family in one run (`tools/bench_families.py`)", "", conditions.sentence(args.seed), "",
             f"Warm: `Estimator.estimate` along one loop of the demo's trajectory, {args.steps} inputs (exact inverse "
             f"kinematics), warm from the previous estimate, solve only, wall clock; error = largest distance to the "
             f"true pose over the geometry's scale; reference: the median time of a fixed piece of interpreter and "
             f"small-array work ({REFERENCE_CALLS} calls just before the warm loop; on this shared virtual machine its "
             f"speed, and the warm solve's, changes by up to 1.8x from one second to the next). Cold: {args.cold} "
             f"inputs at random points of the loop, each by a new `Estimator` (no previous pose; the Delta: its closed "
             f"form) under the node's default budget "
             f"({BUDGET_MS:g} ms): converged share, mean evaluations, median time. Solve-all: `solve_all` with the "
             f"family's default method at the loop's start, the median of {SOLVE_ALL_CALLS} calls after an untimed "
             f"one (a process's first call loads the compiled code). A cold status `budget_exhausted` is the node's "
             f"wall-clock budget running out (the only status that depends on time: on a loaded machine less work fits "
             f"in it); the tests check cold success with a generous budget. Revision {git_revision()}.", "",
             "| manipulator | legs | warm p50 (µs) | warm p99 (µs) | warm p99 not preempted (µs) | warm max (µs) | "
             "preempted | reference p50 (µs) | warm converged | warm error (rel.) | cold converged | "
             "cold, other statuses | cold evaluations (mean) | cold p50 (ms) | solve-all method | modes | "
             "solve-all (s) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for label, r in rows:
        other = ", ".join(f"{s} {n}" for s, n in sorted(r["cold_other"].items())) or "none"
        lines.append(f"| {label} | {r['legs']} | {r['p50']:.1f} | {r['p99']:.1f} | {r['p99_calm']:.1f} | "
                     f"{r['max']:.0f} | {r['preempted']:.1f} % | {r['reference']:.2f} | {r['warm_ok']}/{r['steps']} | "
                     f"{r['error_rel']:.1e} | "
                     f"{r['cold_ok']}/{r['cold']} | {other} | {r['cold_evals']:.0f} | {r['cold_p50_ms']:.2f} | "
                     f"{r['method']} | {r['modes']} | {r['all_s']:.2g} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="bench_families", description=__doc__.split("\n\n")[0])
    p.add_argument("--steps", type=int, default=2000, help="warm solves per manipulator (default 2000)")
    p.add_argument("--cold", type=int, default=100, help="cold solves per manipulator (default 100)")
    p.add_argument("--seed", type=int, default=0, help="seed of the cold inputs' choice (default 0)")
    p.add_argument("--markdown", default=None, help="also write the Markdown here")
    args = p.parse_args(argv)
    if args.steps < 2 * WARM_UP_CALLS or args.cold < 1:
        print(f"error: bench_families: --steps must be at least {2 * WARM_UP_CALLS} and --cold at least 1",
              file=sys.stderr)
        return 2
    rng = np.random.default_rng(args.seed)
    rows, conditions = measured_run(lambda: [(label, measure(name, args.steps, args.cold, rng)) for label, name in
                                             LEG_LENGTH_CONFIGS + tuple(family_configs())])
    emit_report(report(rows, args, conditions), args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
