"""The bench's timing experiments and their sections, on the timed calls every tool shares (:mod:`glpma_tools.timing`):
warm tracking (the Estimator along the simulated loop) beside its peers from the same warm starts, and deadlines.

Rows are ``SimpleNamespace``s.  A warm row: ``label``, ``stats`` (latency distribution, ms) and per step
``latency_s``, ``preempted`` (by another process), ``leg_residual`` (max |IK(x) - legs|) and ``evaluations``
(``latency_s`` None: not installed); the Estimator's also ``budget_ms``, ``errors`` (distance to the true pose),
``statuses`` and ``stages`` (counts).  A deadline row: ``case``, ``solver``, ``label`` (the figure's: the case in
short and the solver) and the fields of its :class:`~glpma_tools.timing.TimedCalls`, with ``overrun_ms``."""
from __future__ import annotations

import functools
import math
from collections import Counter
from types import SimpleNamespace

import numpy as np
from scipy.optimize import least_squares

from glpma_ros import solvers
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.solvers.lm import LEG_RTOL
from glpma_tools import timing
from glpma_tools.sim import trajectories as traj
from glpma_tools.stats import distribution
from glpma_tools.tables import MISSING, fmt, ratio, table
from glpma_tools.timing import DEADLINE_MARGIN_MS, NO_CAP, STOP_AFTER, STOP_OVERRUN_FACTOR, timed_calls, warm_up

from .markdown import figure_link, md_blocks, pct, prose
from .peers import available
from .scenarios import LATENCY_TARGET_MS

#: steps of the loop the tracking warm-up solves (on an Estimator of its own)
WARM_UP_STEPS = 19
#: scipy's variants (method, Jacobian), with tolerances at round-off so that accuracy is comparable
SCIPY_VARIANTS = [("lm", "analytic"), ("trf", "analytic"), ("lm", "2-point"), ("trf", "2-point")]
SCIPY_TOL = 1e-15
#: the NumPy Newton iteration's last step (a plain Newton that has not converged by then will not)
NEWTON_MAX_STEPS = 20
#: the deadline cells are small: a short warm-up is enough
DEADLINE_WARM_UP_QUIET = 3
DEADLINE_WARM_UP_MAX_CALLS = 30


def _solves(label, calls, model, found, given, evaluations, **more) -> SimpleNamespace:
    """A row of solves from the timed ``calls`` and the solutions ``found`` (None: none) for the legs ``given``."""
    residual = [math.inf if x is None else float(np.max(np.abs(model.inverse_kinematics(x) - legs)))
                for x, legs in zip(found, given)]
    return SimpleNamespace(label=label, stats=distribution(calls.elapsed_s, 1e3), latency_s=calls.elapsed_s,
                           preempted=calls.preempted, leg_residual=np.array(residual),
                           evaluations=np.array(evaluations), **more)


def tracking(sc, steps, budget_ms, progress) -> tuple[SimpleNamespace, list[SimpleNamespace]]:
    """``steps`` Estimator solves along one loop from the scenario's start, each warm from the previous one, and its
    peers' rows (a plain NumPy Newton iteration and scipy's variants), each from the same warm starts."""
    model = sc.model
    poses, legs = sc.along(steps + 1)
    spare = Estimator(model, initial_pose=poses[0], time_budget_s=budget_ms / 1e3)
    warm_up(lambda i: spare.estimate(legs[1 + i % min(WARM_UP_STEPS, steps)]), budget_ms)
    est = Estimator(model, initial_pose=poses[0], time_budget_s=budget_ms / 1e3)
    starts = []

    def step(i):
        starts.append(np.array(est.last_x, dtype=float))
        return est.estimate(legs[i + 1])
    calls = timed_calls(step, steps, budget_ms, f"{sc.label} tracking", progress, stop_early=False)
    found = [e.x if e.x is not None and np.all(np.isfinite(e.x)) else None for e in calls.results]
    ours = _solves("ours: Estimator (warm: compiled LM)", calls, model, found, legs[1:],
                   [e.evaluations for e in calls.results], budget_ms=budget_ms,
                   errors=np.array([math.inf if x is None else model.distance(x, t) for x, t in zip(found, poses[1:])]),
                   statuses=Counter(e.status for e in calls.results), stages=Counter(e.start for e in calls.results))
    return ours, _peers(sc, starts, legs[1:], budget_ms, progress)


def _peers(sc, starts, legs, budget_ms, progress) -> list[SimpleNamespace]:
    why = available("scipy")
    peers = {"plain NumPy Newton": functools.partial(numpy_newton, sc.model)}
    if why is None:
        peers.update({f"scipy `{method}`, {jac}": functools.partial(scipy_solve, least_squares, sc.model, method, jac)
                      for method, jac in SCIPY_VARIANTS})
    out, m = [], min(WARM_UP_STEPS, len(legs))
    for label, solve in peers.items():
        warm_up(lambda i, solve=solve: solve(starts[i % m], legs[i % m]), budget_ms)
        calls = timed_calls(lambda k, solve=solve: solve(starts[k], legs[k]), len(legs), budget_ms,
                            f"{sc.label} {label}", progress, stop_early=False)
        found, evaluations = zip(*calls.results)
        out.append(_solves(label, calls, sc.model, found, legs, evaluations))
    return out + [SimpleNamespace(label=f"scipy `{method}`, {jac}", latency_s=None)
                  for method, jac in SCIPY_VARIANTS if why is not None]


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
    state, met = model.pose_state(x_start), 0
    for nfev in range(1, NEWTON_MAX_STEPS + 2):
        r, J = model.pose_residuals_jacobian(state, legs)
        met += bool(np.max(np.abs(r)) <= tol)
        if met == 2 or nfev > NEWTON_MAX_STEPS:     # the step after the criterion first held is done, or the last
            break
        try:
            step = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:               # singular Jacobian: a plain Newton stops here
            break
        state = model.pose_retract(state, step)
    return model.pose_variables(state), nfev


# -- the report's sections: tracking -------------------------------------------------------------------------
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
    """The Estimator's latency and accuracy along the loop against its target, per manipulator; then beside its
    peers from the same warm starts, with our latency over theirs (two sections)."""
    def size(kind, share):
        """A size of the loop: in the config's unit when its scenario ran, else as a share of the scale."""
        model = next((sc.model for sc in res["scenarios"].values() if sc.model.kind == kind), None)
        return f"{share * model.scale:.3g} {model.unit}" if model else f"{100 * share:g} % of the scale"
    body, versus = [], []
    for key, ours in res["tracking"].items():
        label, target = res["scenarios"][key].label, LATENCY_TARGET_MS[key]
        verdict = "met" if ours.stats["p99"] <= target else (
            "**missed** (met without preemption)" if calm_distribution(ours.latency_s, ours.preempted)["p99"] <= target
            else "**missed**")
        body.append([label, len(ours.latency_s), f"{ours.budget_ms:g}", *_solves_cells(ours), f"≤ {target:g}",
                     verdict, f"{np.max(ours.errors):.2e}", *(", ".join(f"{k} {v}" for k, v in sorted(count.items()))
                                                              for count in (ours.statuses, ours.stages))])
        ran = [r for r in (ours, *res["scipy"][key]) if r.latency_s is not None]
        missing = [r.label for r in res["scipy"][key] if r.latency_s is None]
        versus += [f"### {label} ({len(ours.latency_s)} steps)",
                   table(["solver", *SOLVES_HEAD, "ours/row (p50)", "ours/row (p99)"],
                         [[r.label, *_solves_cells(r), *(ratio(ours.stats[q], r.stats[q]) for q in ("p50", "p99"))]
                          for r in ran]),
                   missing and "Not installed: " + "; ".join(missing) + "."]
    return md_blocks("## Warm tracking latency (solve only)",
                     prose("tracking", planar_radius=size("planar_3rpr", traj.PLANAR_RADIUS),
                           planar_swing=f"{math.degrees(traj.PLANAR_SWING_RAD):.2g}",
                           spatial_radius=size("hexapod_66", traj.SPATIAL_RADIUS),
                           spatial_rise=size("hexapod_66", traj.SPATIAL_RISE),
                           spatial_twist=f"{math.degrees(traj.SPATIAL_TWIST_RAD):.2g}"),
                     table(["manipulator", "steps", "budget ms", *SOLVES_HEAD, "target p99", "", "max error mm",
                            "status", "stage"], body),
                     *(figure_link(res, f"latency_{key}", md_path, f"{res['scenarios'][key].label} latency")
                       for key in res["tracking"]),
                     "## Warm solve against `scipy.optimize.least_squares`", prose("scipy"), *versus,
                     prose("scipy", "note"))


# -- deadlines -----------------------------------------------------------------------------------------------
def deadlines(scenarios, budgets_ms, n, progress, names=None) -> list[SimpleNamespace]:
    """The bench's deadline experiment: cold searches that cannot converge, stopped only by their time
    budget (every registered solver, and the Estimator as the node runs it, cold: every stage runs until the
    deadline)."""

    def search(name, model, legs, polish, budget_ms):
        return lambda seed: solvers.solve(name, model, legs, rng=seed, polish=polish, budget_s=budget_ms / 1e3,
                                          max_evals=NO_CAP)

    def cold(model, legs, budget_ms):
        est = Estimator(model, time_budget_s=budget_ms / 1e3)

        def call(_):
            est.reset()
            est.estimate(legs)
        return call
    cells = []          # (case, case in short, solver, budget ms, call(seed))
    for sc in scenarios:
        infeasible = timing.infeasible_legs(sc.model)
        cases = [(f"{sc.label}, infeasible legs, default (polish)", f"{sc.label} infeasible", infeasible, True)]
        if sc.key == "hexapod":
            cases.insert(0, (f"{sc.label}, feasible legs, pure (cannot converge in ms)", f"{sc.label} pure",
                             sc.legs, False))
        cells += [(case, short, name, b, search(name, sc.model, legs, polish, b))
                  for case, short, legs, polish in cases for name in names or solvers.SOLVERS for b in budgets_ms]
        cells += [(f"{sc.label}, infeasible legs, Estimator (GLPMA, cold, its default evaluation cap)",
                   f"{sc.label} infeasible, cold", "Estimator", b, cold(sc.model, infeasible, b)) for b in budgets_ms]
    rows = []
    for case, short, solver, b, call in cells:
        warm_up(call, b, DEADLINE_WARM_UP_QUIET, DEADLINE_WARM_UP_MAX_CALLS)
        calls = timed_calls(call, n, b, f"deadline {short} {solver} {b:g} ms", progress)
        rows.append(SimpleNamespace(**{**vars(calls), "results": []}, overrun_ms=calls.overrun_ms, case=case,
                                    solver=solver, label=f"{short} | {solver}"))
    return rows


# -- the report's section: deadlines -------------------------------------------------------------------------
def all_overruns(rows) -> tuple[np.ndarray, np.ndarray]:
    """The overruns (ms) of every deadline solve, and of those not preempted."""
    return np.concatenate([r.overrun_ms for r in rows]), np.concatenate([r.overrun_ms[~r.preempted] for r in rows])


def share_on_time(over) -> float:
    """The share (%) of the overruns ``over`` (ms) within the margin."""
    return 100.0 * float(np.mean(over <= DEADLINE_MARGIN_MS))


def worst_overrun(over) -> str:
    """The largest of the overruns ``over`` (ms), signed; a dash when there are none."""
    return f"{float(np.max(over)):+.3f}" if over.size else MISSING


def deadline_section(res, md_path) -> list[str]:
    """Each cell's solves on time and overruns, with and without the preempted ones, and the totals."""
    rows = res["deadline"]

    def on_time(over):
        return pct(share_on_time(over), 4) if over.size else MISSING
    body = [[r.case, r.solver, f"{r.budget_ms:g}", f"{len(over)} (stopped)" if r.stopped_early else len(over),
             on_time(over), fmt(distribution(r.elapsed_s, 1e3)["p99"]), worst_overrun(over), int(np.sum(r.preempted)),
             on_time(calm), worst_overrun(calm)]
            for r in rows for over, calm in [(r.overrun_ms, r.overrun_ms[~r.preempted])]]
    total, calm = all_overruns(rows)
    late = sorted({r.solver for r in rows if np.any(r.overrun_ms[~r.preempted] > DEADLINE_MARGIN_MS)})
    return md_blocks(
        "## Deadline honouring",
        prose("deadline", margin=DEADLINE_MARGIN_MS, stop_after=STOP_AFTER, stop_factor=f"{STOP_OVERRUN_FACTOR:g}"),
        calm.size and prose("deadline", "overall", on_time=on_time(total), solves=total.size,
                            worst=worst_overrun(total), preempted=total.size - calm.size, calm_on_time=on_time(calm),
                            calm_worst=worst_overrun(calm)),
        late and "Late without preemption (the solver itself overran): " + ", ".join(f"`{x}`" for x in late) + ".",
        table(["case", "solver", "budget ms", "solves", "on time", "p99 elapsed ms", "worst overrun ms", "preempted",
               "on time, not preempted", "worst overrun, not preempted"], body),
        figure_link(res, "deadline", md_path, "deadline overruns"))
