"""Warm tracking: the Estimator along the simulated loop (solve time per step, accuracy), and
``scipy.optimize.least_squares`` from the same warm starts."""
from __future__ import annotations

import functools
import math
from collections import Counter
from dataclasses import dataclass

import numpy as np

from glpma_ros.estimator import Estimator
from glpma_tools.sim import trajectories as traj
from glpma_tools.stats import distribution
from glpma_tools.tables import MISSING, fmt, ratio, table
from glpma_tools.timing import timed_calls, warm_up

from .peers import available
from .report import figure_link, md_blocks, prose
from .scenarios import LATENCY_TARGET_MS

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


# -- the report's sections ----------------------------------------------------------------------------
def calm_distribution(latency_s, preempted) -> dict:
    """The distribution (ms) of the calls not preempted (all of them when every one was)."""
    return distribution(latency_s[~preempted] if np.any(~preempted) else latency_s, 1e3)


def tracking_section(res, md_path) -> list[str]:
    scales = {sc.model.kind: (sc.model.scale, sc.model.unit) for sc in res["scenarios"].values()}

    def size(kind, share):
        """A size of the loop: in the config's unit when its scenario ran, else as a share of the scale."""
        return (f"{share * scales[kind][0]:.3g} {scales[kind][1]}" if kind in scales
                else f"{100 * share:g} % of the scale")
    body = []
    for key, t in res["tracking"].items():
        st, calm, target = t.stats, calm_distribution(t.latency_s, t.preempted), LATENCY_TARGET_MS[key]
        verdict = "met" if st["p99"] <= target else (
            "**missed** (met without preemption)" if calm["p99"] <= target else "**missed**")
        body.append([res["scenarios"][key].label, t.steps, f"{t.budget_ms:g}", fmt(st["p50"]), fmt(st["p99"]),
                     fmt(st["max"]), int(np.sum(t.preempted)), fmt(calm["p99"]), fmt(calm["max"]), f"≤ {target:g}",
                     verdict, f"{np.max(t.errors):.2e}", f"{np.max(t.leg_residual):.2e}",
                     ", ".join(f"{k} {v}" for k, v in sorted(t.statuses.items())),
                     ", ".join(f"{k} {v}" for k, v in sorted(t.stages.items())), fmt(float(np.mean(t.evaluations)))])
    return md_blocks("## Warm tracking latency (solve only)",
                     prose("tracking", planar_radius=size("planar_3rpr", traj.PLANAR_RADIUS),
                           planar_swing=f"{math.degrees(traj.PLANAR_SWING_RAD):.2g}",
                           spatial_radius=size("hexapod_66", traj.SPATIAL_RADIUS),
                           spatial_rise=size("hexapod_66", traj.SPATIAL_RISE),
                           spatial_twist=f"{math.degrees(traj.SPATIAL_TWIST_RAD):.2g}"),
                     table(["manipulator", "steps", "budget ms", "p50 ms", "p99 ms", "max ms", "preempted steps",
                            "p99 ms not preempted", "max ms not preempted", "target p99", "",
                            "max error mm", "max leg residual mm", "status", "stage", "mean evals"], body),
                     *(figure_link(res, f"latency_{key}", md_path, f"{res['scenarios'][key].label} latency")
                       for key in res["tracking"]))


def _scipy_row(label, ours, latency_s, preempted, residual, evals) -> list:
    """A row of the scipy table: the latency (ms, and of the calls not preempted unless ``preempted`` is None),
    the leg residuals and evaluations of ``label``, its latency against ``ours``."""
    s = distribution(latency_s, 1e3)
    calm = s if preempted is None else distribution(latency_s[~preempted], 1e3)
    return [label, fmt(s["p50"]), fmt(s["p99"]), fmt(calm["p99"]), fmt(s["mean"]), f"{np.median(residual):.1e}",
            f"{np.max(residual):.1e}", fmt(float(np.mean(evals))), ratio(ours["p50"], s["p50"]),
            ratio(ours["p99"], s["p99"])]


def scipy_section(res, md_path) -> list[str]:
    out = md_blocks("## Warm solve against `scipy.optimize.least_squares`", prose("scipy"))
    for key, rows in res["scipy"].items():
        t = res["tracking"][key]
        ours = distribution(t.latency_s, 1e3)
        labels = ["plain NumPy Newton" if r.method == "newton" else f"scipy `{r.method}`, {r.jac}" for r in rows]
        body = [_scipy_row("ours: Estimator (warm: compiled LM)", ours, t.latency_s, t.preempted, t.leg_residual,
                           t.evaluations)]
        body += [_scipy_row(label, ours, r.latency_s, r.preempted, r.leg_residual, r.nfev) if r.status == "run"
                 else [label] + [MISSING] * 7 + [r.status, ""] for label, r in zip(labels, rows)]
        out += md_blocks(f"### {res['scenarios'][key].label} ({t.steps} steps)",
                         table(["solver", "p50 ms", "p99 ms", "p99 ms not preempted", "mean ms",
                                "median max leg residual", "worst max leg residual", "mean evals", "ours/row (p50)",
                                "ours/row (p99)"], body))
    return out + md_blocks(prose("scipy", "note"))


# -- the warm case's peers: scipy.optimize.least_squares and a plain NumPy Newton iteration -------------
def _left_jacobian(w):
    """Left Jacobian of SO(3): exp(w + dw) = exp(J_l(w) dw) exp(w) to first order."""
    theta = math.sqrt(float(w @ w))
    K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if theta < 1e-6:
        return np.eye(3) + 0.5 * K + K @ K / 6.0
    return (np.eye(3) + ((1.0 - math.cos(theta)) / theta ** 2) * K
            + ((theta - math.sin(theta)) / theta ** 3) * K @ K)


class ScipyWarm:
    """One warm-started ``least_squares`` solve per call.

    ``jac="analytic"``: leg residuals in the model's pose parameterisation with the model's analytic Jacobian (3-RPR:
    the variables; hexapod: position plus a rotation vector ``w`` applied as ``exp(w) R0`` (``pose_retract``),
    Jacobian composed with the left Jacobian of SO(3), exact).  ``jac="2-point"``: the solver's own residual vector of
    the solver variables (hexapod: the nine-variable model with its rigidity terms) and finite differences."""

    def __init__(self, model, method, jac, tol=1e-15):
        from scipy.optimize import least_squares
        self.least_squares = least_squares
        self.model, self.method, self.jac, self.tol = model, method, jac, tol

    def solve(self, x_start, legs):
        """Returns (variables, nfev)."""
        model, x0 = self.model, np.asarray(x_start, dtype=float)
        kw = {"method": self.method, "xtol": self.tol, "ftol": self.tol, "gtol": self.tol}
        if self.jac == "2-point":
            res = self.least_squares(lambda x: model.residuals(x, legs)[0], x0, **kw)
            return res.x, res.nfev
        planar, start = model.kind == "planar_3rpr", model.pose_state(x0)

        def pose(s):                # 3-RPR: the variables are the pose; hexapod: a step from the start
            return s if planar else model.pose_retract(start, s)

        @functools.lru_cache(maxsize=1)     # least_squares asks for the residuals and the Jacobian at one point
        def rj(key):
            s = np.frombuffer(key)
            r, J = model.pose_residuals_jacobian(pose(s), legs)
            return r, J if planar else np.hstack((J[:, :3], J[:, 3:] @ _left_jacobian(s[3:])))

        res = self.least_squares(lambda s: rj(s.tobytes())[0], x0 if planar else np.zeros(6),
                                 jac=lambda s: rj(s.tobytes())[1], **kw)
        return model.pose_variables(pose(res.x)), res.nfev


SCIPY_VARIANTS = [("lm", "analytic"), ("trf", "analytic"), ("lm", "2-point"), ("trf", "2-point")]


class NumpyNewton:
    """A plain NumPy Gauss-Newton iteration from the warm start: what a user writes in a few lines with the model's
    pose parameterisation and analytic Jacobian (``pose_residuals_jacobian``, ``pose_retract``), undamped, stopped by
    the same leg criterion as ours (``max |r| <= LEG_RTOL * max(scale, max leg)``, then one more step) or after
    ``max_iter`` steps."""

    method, jac = "newton", "numpy"

    def __init__(self, model, max_iter=20):
        from glpma_ros.solvers.lm import LEG_RTOL
        self.model, self.max_iter, self.rtol = model, max_iter, LEG_RTOL

    def solve(self, x_start, legs):
        """Returns (variables, evaluations)."""
        model = self.model
        tol = self.rtol * max(model.scale, float(np.max(legs)))
        state = model.pose_state(x_start)
        r, J = model.pose_residuals_jacobian(state, legs)
        nfev, extra = 1, 1
        for _ in range(self.max_iter):
            if np.max(np.abs(r)) <= tol:
                if extra == 0:
                    break
                extra -= 1
            try:
                step = np.linalg.solve(J, -r)
            except np.linalg.LinAlgError:       # singular Jacobian: a plain Newton stops here
                break
            state = model.pose_retract(state, step)
            r, J = model.pose_residuals_jacobian(state, legs)
            nfev += 1
        return model.pose_variables(state), nfev
