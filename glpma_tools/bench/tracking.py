"""Warm tracking: the Estimator along the simulated loop (solve time per step, accuracy), and
``scipy.optimize.least_squares`` from the same warm starts."""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np

from glpma_ros.estimator import Estimator
from glpma_tools.stats import distribution
from glpma_tools.timing import timed_calls, warm_up

from .peers import SCIPY_VARIANTS, NumpyNewton, ScipyWarm, available

#: steps of the loop the warm-up solves (on an Estimator of its own)
WARM_UP_STEPS = 19


@dataclass
class Tracking:
    steps: int
    budget_ms: float
    latency_s: np.ndarray
    errors: np.ndarray            # distance to the true pose (config unit)
    leg_residual: np.ndarray      # max |IK(x) - legs| per step
    statuses: dict
    stages: dict
    evaluations: np.ndarray
    starts: np.ndarray            # the warm start of each step (previous estimate)
    legs: np.ndarray
    preempted: np.ndarray         # the step was preempted by another process (involuntary context switch)

    @property
    def stats(self) -> dict:
        return distribution(self.latency_s, 1e3)


def max_leg_residual(model, x, legs) -> float:
    return float(np.max(np.abs(model.inverse_kinematics(x) - legs)))


def tracking(sc, steps, budget_ms, progress) -> Tracking:
    """``steps`` Estimator solves along one loop from the scenario's start, warm from the previous one."""
    model = sc.model
    traj, legs_all = sc.along(steps + 1)
    spare = Estimator(model, initial_pose=traj[0], time_budget_s=budget_ms / 1e3)
    warm_up(lambda i: spare.estimate(legs_all[1 + i % WARM_UP_STEPS]), budget_ms)
    est = Estimator(model, initial_pose=traj[0], time_budget_s=budget_ms / 1e3)
    starts = []

    def step(i):
        starts.append(np.array(est.last_x, dtype=float))
        return est.estimate(legs_all[i + 1])

    calls = timed_calls(step, steps, budget_ms, f"{sc.label} tracking", progress, stop_early=False)
    found = [e.x if e.x is not None and np.all(np.isfinite(e.x)) else None for e in calls.results]
    return Tracking(steps, budget_ms, calls.elapsed_s,
                    np.array([math.inf if x is None else model.distance(x, t) for x, t in zip(found, traj[1:])]),
                    np.array([math.inf if x is None else max_leg_residual(model, x, legs)
                              for x, legs in zip(found, legs_all[1:])]),
                    dict(Counter(e.status for e in calls.results)), dict(Counter(e.start for e in calls.results)),
                    np.array([e.evaluations for e in calls.results]), np.array(starts), legs_all[1:], calls.preempted)


@dataclass
class ScipyRow:
    method: str
    jac: str
    latency_s: np.ndarray = None
    leg_residual: np.ndarray = None
    nfev: np.ndarray = None
    preempted: np.ndarray = None
    status: str = "run"
    note: str = ""


def scipy_warm(sc, trk: Tracking, progress) -> list[ScipyRow]:
    """scipy's variants and a plain NumPy Newton iteration, each from the Estimator's warm starts."""
    model, why = sc.model, available("scipy")
    if why is not None:
        print(f"bench: scipy {why}; its rows are marked 'not installed'")
    out, m = [], min(WARM_UP_STEPS, len(trk.legs))
    for solver in [NumpyNewton(model)] + [ScipyWarm(model, *variant) for variant in SCIPY_VARIANTS if why is None]:
        warm_up(lambda i, solver=solver: solver.solve(trk.starts[i % m], trk.legs[i % m]), trk.budget_ms)
        calls = timed_calls(lambda k, solver=solver: solver.solve(trk.starts[k], trk.legs[k]), len(trk.legs),
                            trk.budget_ms, f"{sc.label} {solver.method}/{solver.jac}", progress, stop_early=False)
        residual = [max_leg_residual(model, x, legs) for (x, _), legs in zip(calls.results, trk.legs)]
        out.append(ScipyRow(solver.method, solver.jac, calls.elapsed_s, np.array(residual),
                            np.array([n for _, n in calls.results]), calls.preempted))
    return out + [ScipyRow(*variant, status="not installed", note=why) for variant in SCIPY_VARIANTS if why is not None]
