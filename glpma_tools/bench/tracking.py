"""Warm tracking: the Estimator along the simulated loop (solve time per step, accuracy), and its peers from the
same warm starts (``scipy.optimize.least_squares``, a plain NumPy Newton iteration); their two sections.

A row of solves (a ``SimpleNamespace``): ``label``, ``stats`` (latency distribution, ms) and per step ``latency_s``,
``preempted`` (by another process), ``leg_residual`` (max |IK(x) - legs|) and ``evaluations`` (``latency_s`` None:
not installed); the Estimator's also ``budget_ms``, ``errors`` (distance to the true pose), ``statuses`` and
``stages`` (counts), and each step's warm start and legs (``starts``, ``legs``: its peers' inputs)."""
from __future__ import annotations

import functools
import math
from collections import Counter
from types import SimpleNamespace

import numpy as np

from glpma_ros.estimator import Estimator
from glpma_ros.solvers.lm import LEG_RTOL
from glpma_tools.sim import trajectories as traj
from glpma_tools.stats import distribution
from glpma_tools.tables import fmt, ratio, table
from glpma_tools.timing import timed_calls, warm_up

from .peers import available
from .report import figure_link, md_blocks, prose
from .scenarios import LATENCY_TARGET_MS

#: steps of the loop the warm-up solves (on an Estimator of its own)
WARM_UP_STEPS = 19
#: scipy's variants (method, Jacobian), with tolerances at round-off so that accuracy is comparable
SCIPY_VARIANTS = [("lm", "analytic"), ("trf", "analytic"), ("lm", "2-point"), ("trf", "2-point")]
SCIPY_TOL = 1e-15
#: the peer the latency figures draw beside ours
DRAWN_PEER = "scipy `lm`, analytic"
NEWTON_MAX_STEPS = 20


def _solves(label, calls, model, found, given, evaluations, **more) -> SimpleNamespace:
    """A row of solves from the timed ``calls`` and the solutions ``found`` (None: none) for the legs ``given``."""
    residual = [math.inf if x is None else float(np.max(np.abs(model.inverse_kinematics(x) - legs)))
                for x, legs in zip(found, given)]
    return SimpleNamespace(label=label, stats=distribution(calls.elapsed_s, 1e3), latency_s=calls.elapsed_s,
                           preempted=calls.preempted, leg_residual=np.array(residual),
                           evaluations=np.array(evaluations), **more)


def tracking(sc, steps, budget_ms, progress) -> SimpleNamespace:
    """``steps`` Estimator solves along one loop from the scenario's start, each warm from the previous one."""
    model = sc.model
    poses, legs = sc.along(steps + 1)
    spare = Estimator(model, initial_pose=poses[0], time_budget_s=budget_ms / 1e3)
    warm_up(lambda i: spare.estimate(legs[1 + i % WARM_UP_STEPS]), budget_ms)
    est = Estimator(model, initial_pose=poses[0], time_budget_s=budget_ms / 1e3)
    starts = []

    def step(i):
        starts.append(np.array(est.last_x, dtype=float))
        return est.estimate(legs[i + 1])
    calls = timed_calls(step, steps, budget_ms, f"{sc.label} tracking", progress, stop_early=False)
    found = [e.x if e.x is not None and np.all(np.isfinite(e.x)) else None for e in calls.results]
    return _solves("ours: Estimator (warm: compiled LM)", calls, model, found, legs[1:],
                   [e.evaluations for e in calls.results], budget_ms=budget_ms, starts=np.array(starts), legs=legs[1:],
                   errors=np.array([math.inf if x is None else model.distance(x, t) for x, t in zip(found, poses[1:])]),
                   statuses=Counter(e.status for e in calls.results), stages=Counter(e.start for e in calls.results))


def scipy_warm(sc, ours, progress) -> list[SimpleNamespace]:
    """The Estimator's peers, each from its warm starts: a plain NumPy Newton iteration and scipy's variants."""
    why = available("scipy")
    peers = {"plain NumPy Newton": functools.partial(numpy_newton, sc.model)}
    if why is None:
        from scipy.optimize import least_squares
        peers.update({f"scipy `{method}`, {jac}": functools.partial(scipy_solve, least_squares, sc.model, method, jac)
                      for method, jac in SCIPY_VARIANTS})
    out, m = [], min(WARM_UP_STEPS, len(ours.legs))
    for label, solve in peers.items():
        warm_up(lambda i, solve=solve: solve(ours.starts[i % m], ours.legs[i % m]), ours.budget_ms)
        calls = timed_calls(lambda k, solve=solve: solve(ours.starts[k], ours.legs[k]), len(ours.legs),
                            ours.budget_ms, f"{sc.label} {label}", progress, stop_early=False)
        found, evaluations = zip(*calls.results)
        out.append(_solves(label, calls, sc.model, found, ours.legs, evaluations))
    return out + [SimpleNamespace(label=f"scipy `{method}`, {jac}", latency_s=None)
                  for method, jac in SCIPY_VARIANTS if why is not None]


# -- the report's sections ----------------------------------------------------------------------------
def calm_distribution(latency_s, preempted) -> dict:
    """The distribution (ms) of the calls not preempted (all of them when every one was)."""
    return distribution(latency_s[~preempted] if np.any(~preempted) else latency_s, 1e3)


#: the latency and accuracy columns of both sections' tables (:func:`_solves_cells`)
SOLVES_HEAD = ["p50 ms", "p99 ms", "max ms", "preempted", "p99 ms not preempted", "max ms not preempted", "mean ms",
               "median max leg residual", "worst max leg residual", "mean evals"]


def _solves_cells(row) -> list:
    s, calm = row.stats, calm_distribution(row.latency_s, row.preempted)
    return [fmt(s["p50"]), fmt(s["p99"]), fmt(s["max"]), int(np.sum(row.preempted)), fmt(calm["p99"]),
            fmt(calm["max"]), fmt(s["mean"]), f"{np.median(row.leg_residual):.1e}", f"{np.max(row.leg_residual):.1e}",
            fmt(float(np.mean(row.evaluations)))]


def tracking_section(res, md_path) -> list[str]:
    """The Estimator's latency and accuracy along the loop against its target, per manipulator."""
    def size(kind, share):
        """A size of the loop: in the config's unit when its scenario ran, else as a share of the scale."""
        model = next((sc.model for sc in res["scenarios"].values() if sc.model.kind == kind), None)
        return f"{share * model.scale:.3g} {model.unit}" if model else f"{100 * share:g} % of the scale"
    body = []
    for key, t in res["tracking"].items():
        calm_p99, target = calm_distribution(t.latency_s, t.preempted)["p99"], LATENCY_TARGET_MS[key]
        verdict = "met" if t.stats["p99"] <= target else (
            "**missed** (met without preemption)" if calm_p99 <= target else "**missed**")
        body.append([res["scenarios"][key].label, len(t.latency_s), f"{t.budget_ms:g}", *_solves_cells(t),
                     f"≤ {target:g}", verdict, f"{np.max(t.errors):.2e}",
                     *(", ".join(f"{k} {v}" for k, v in sorted(count.items())) for count in (t.statuses, t.stages))])
    return md_blocks("## Warm tracking latency (solve only)",
                     prose("tracking", planar_radius=size("planar_3rpr", traj.PLANAR_RADIUS),
                           planar_swing=f"{math.degrees(traj.PLANAR_SWING_RAD):.2g}",
                           spatial_radius=size("hexapod_66", traj.SPATIAL_RADIUS),
                           spatial_rise=size("hexapod_66", traj.SPATIAL_RISE),
                           spatial_twist=f"{math.degrees(traj.SPATIAL_TWIST_RAD):.2g}"),
                     table(["manipulator", "steps", "budget ms", *SOLVES_HEAD, "target p99", "", "max error mm",
                            "status", "stage"], body),
                     *(figure_link(res, f"latency_{key}", md_path, f"{res['scenarios'][key].label} latency")
                       for key in res["tracking"]))


def scipy_section(res, md_path) -> list[str]:
    """Ours beside its peers from the same warm starts, per manipulator, and our latency over theirs."""
    out = md_blocks("## Warm solve against `scipy.optimize.least_squares`", prose("scipy"))
    for key, peers in res["scipy"].items():
        ours, missing = res["tracking"][key], [r.label for r in peers if r.latency_s is None]
        body = [[r.label, *_solves_cells(r), ratio(ours.stats["p50"], r.stats["p50"]),
                 ratio(ours.stats["p99"], r.stats["p99"])] for r in (ours, *peers) if r.latency_s is not None]
        out += md_blocks(f"### {res['scenarios'][key].label} ({len(ours.latency_s)} steps)",
                         table(["solver", *SOLVES_HEAD, "ours/row (p50)", "ours/row (p99)"], body),
                         missing and "Not installed: " + ", ".join(missing) + ".")
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


def scipy_solve(least_squares, model, method, jac, x_start, legs):
    """One warm-started ``least_squares`` solve, ``(variables, nfev)``.  ``jac="analytic"``: leg residuals in the
    model's pose parameterisation, its analytic Jacobian (hexapod: a step of position and rotation vector ``w``,
    ``exp(w) R0``, the Jacobian composed with SO(3)'s left Jacobian: exact); ``"2-point"``: the residual vector of
    the solver variables (hexapod: nine, with the rigidity terms) and finite differences."""
    options = {"method": method, "xtol": SCIPY_TOL, "ftol": SCIPY_TOL, "gtol": SCIPY_TOL}
    x0 = np.asarray(x_start, dtype=float)
    if jac == "2-point":
        res = least_squares(lambda x: model.residuals(x, legs)[0], x0, **options)
        return res.x, res.nfev
    planar, start = model.kind == "planar_3rpr", model.pose_state(x0)

    def pose(s):                # 3-RPR: the variables are the pose; hexapod: a step from the start
        return s if planar else model.pose_retract(start, s)

    @functools.lru_cache(maxsize=1)     # least_squares asks for the residuals and the Jacobian at one point
    def rj(key):
        s = np.frombuffer(key)
        r, J = model.pose_residuals_jacobian(pose(s), legs)
        return r, J if planar else np.hstack((J[:, :3], J[:, 3:] @ _left_jacobian(s[3:])))
    res = least_squares(lambda s: rj(s.tobytes())[0], x0 if planar else np.zeros(6), jac=lambda s: rj(s.tobytes())[1],
                        **options)
    return model.pose_variables(pose(res.x)), res.nfev


def numpy_newton(model, x_start, legs):
    """A plain NumPy Gauss-Newton iteration from the warm start, ``(variables, evaluations)``: what a user writes with
    the model's pose parameterisation and analytic Jacobian, undamped, stopped by the Estimator's leg criterion
    (``max |r| <= LEG_RTOL * max(scale, max leg)``, then one more step) or after :data:`NEWTON_MAX_STEPS` steps."""
    tol = LEG_RTOL * max(model.scale, float(np.max(legs)))
    state = model.pose_state(x_start)
    r, J = model.pose_residuals_jacobian(state, legs)
    nfev, met = 1, 0
    for _ in range(NEWTON_MAX_STEPS):
        met += bool(np.max(np.abs(r)) <= tol)
        if met == 2:                            # the step after the criterion first held is done
            break
        try:
            step = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:           # singular Jacobian: a plain Newton stops here
            break
        state = model.pose_retract(state, step)
        r, J = model.pose_residuals_jacobian(state, legs)
        nfev += 1
    return model.pose_variables(state), nfev
