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
import os
from collections import Counter
from types import SimpleNamespace

import numpy as np
from scipy.optimize import least_squares

from glpma_ros import solvers
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.node import realtime
from glpma_ros.runtime import precompile
from glpma_ros.solvers.lm import LEG_RTOL
from glpma_tools import stalls, timing
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
#: the load conditions of the deadline experiment: no load added (the machine is shared: its own load is said in
#: the report's header), then one busy loop per core, then the same with the measuring thread under SCHED_FIFO
#: (the node's thread_priority; measured where the process may use it)
LOADS = ("no load added", "every core busy", "every core busy, SCHED_FIFO")
#: the SCHED_FIFO priority of the last load condition
FIFO_PRIORITY = 10
#: ... and the sleep before each of its solves: a real-time thread that never sleeps is throttled by the
#: kernel (sched_rt_runtime_us: 50 ms of every second), which a node answering inputs never meets
FIFO_REST_S = 1e-3
#: the quantile of (end - deadline) the deadline section reports besides the largest
TAIL_QUANTILE = 99.9
#: a solve that ends more than this (ms) after its deadline is listed apart with the split of its lateness:
#: what a solver may overrun at the tail (p99.9) for the deadline to hold
LATE_MS = 0.1
#: ... at most this many of them per load, the latest first
LATE_LISTED = 8
#: why a listed solve was late: its thread's CPU time ran past the budget by more than LATE_MS (its code, or
#: interrupts served on its core: a kernel without IRQ time accounting counts them as the thread's time) ...
RAN_PAST = "on its core past the deadline"
#: ... or not: the time off its core explains the lateness
OFF_CORE = "off its core (the OS took it)"


def deadlines(scenarios, budgets_ms, n, progress, names=None, loads=LOADS, stall_seconds=0.0) -> list[SimpleNamespace]:
    """The bench's deadline experiment, under each of ``loads``: every registered solver (evaluation cap
    10^9: only the deadline or convergence stops it) on feasible legs and on legs without a real assembly, and
    the Estimator as the node runs it, cold, on feasible legs, on legs without an assembly that its probe must
    tell, and on legs the loop bounds of a pair of legs tell at once; beside them, at each budget, a compiled loop
    that only reads the clock until its deadline (:func:`glpma_tools.stalls.spin_until`: what the machine lets any
    solver do).  A row per cell, with the statuses; per
    load, a row of the smallest deciding budgets and (``stall_seconds`` > 0) one of the machine's own stalls
    (:mod:`glpma_tools.stalls`), probed that long in all, a share after each cell so that it samples the
    cells' time, in bursts of the largest budget with the cells' rest between them."""

    def search(name, model, legs, budget_ms):
        def call(seed):
            return solvers.solve(name, model, legs, rng=seed, budget_s=budget_ms / 1e3, max_evals=NO_CAP).status
        return call

    estimators = []             # (manipulator, load, Estimator): their smallest deciding budgets after the cells

    def cold(model, legs, budget_ms):
        est = Estimator(model, time_budget_s=budget_ms / 1e3)
        estimators.append((model.kind, est))

        def call(_):
            est.reset()
            return est.estimate(legs).status
        return call
    cells = []          # (case, case in short, solver, budget ms, call(seed))
    for sc in scenarios:
        probed, told = timing.probed_infeasible_legs(sc.model), timing.infeasible_legs(sc.model)
        cases = [(f"{sc.label}, feasible legs", f"{sc.label} feasible", sc.legs),
                 (f"{sc.label}, legs without an assembly", f"{sc.label} infeasible", probed)]
        cells += [(case, short, name, b, search(name, sc.model, legs, b))
                  for case, short, legs in cases for name in names or solvers.SOLVERS for b in budgets_ms]
        cases.append((f"{sc.label}, legs without an assembly, told by a pair's loop bounds", f"{sc.label} told", told))
        cells += [(f"{case} (Estimator: GLPMA, cold)", short, "Estimator", b, cold(sc.model, legs, b))
                  for case, short, legs in cases for b in budgets_ms]
    # the machine's floor beside the solvers: a "solver" that only reads the clock until its deadline, as many times
    # at each budget as a solver is timed in all (one cell per case and manipulator)
    floor_solves = n * sum(1 for cell in cells if cell[2] == cells[0][2] and cell[3] == cells[0][3])
    cells += [("a loop that only reads the clock until its deadline (no solve: the machine's floor)", "machine floor",
               stalls.CLOCK_ONLY, b, lambda _, b=b: stalls.clock_only(b / 1e3)) for b in budgets_ms]
    # every compiled path a cell may take loaded before any is timed, as the node's warm-up does: a kernel's first
    # use loads it from Numba's cache, tens of milliseconds inside the solve that happens to need it first (the
    # cells' own warm-up stops after a few quick calls, which need not take every path)
    for sc in scenarios:
        for name in dict.fromkeys([*(names or solvers.SOLVERS), *(est.solver for _, est in estimators)]):
            precompile.exercise(sc.model, name)
    rows = []
    for load in loads:
        fifo = load == LOADS[2]
        with timing.busy_cores(0 if load == LOADS[0] else os.cpu_count() or 1):
            # after the busy loops started: they must not inherit the real-time policy
            if fifo and realtime.apply(realtime.RealtimeSettings(FIFO_PRIORITY)):
                continue                    # not allowed here: the report says so
            for _, est in estimators:       # measured again under this load
                est.calibrate()
            probed = []
            for case, short, solver, b, call in cells:
                warm_up(call, b, DEADLINE_WARM_UP_QUIET, DEADLINE_WARM_UP_MAX_CALLS)
                calls = timed_calls(call, floor_solves if solver == stalls.CLOCK_ONLY else n, b,
                                    f"deadline {short} {solver} {b:g} ms, {load}", progress,
                                    stop_early=False, rest_s=FIFO_REST_S if fifo else 0.0)
                rows.append(SimpleNamespace(**{**vars(calls), "results": []}, overrun_ms=calls.overrun_ms, case=case,
                                            solver=solver, load=load, statuses=Counter(calls.results),
                                            label=f"{short} | {solver}" + {LOADS[1]: " | busy",
                                                                           LOADS[2]: " | busy, FIFO"}.get(load, "")))
                if stall_seconds > 0:
                    probed.append(stalls.probe(stall_seconds / len(cells), max(budgets_ms) / 1e3,
                                               FIFO_REST_S if fifo else 0.0))
        if probed:
            rows.append(SimpleNamespace(stalls=stalls.Stalls.joined(probed), load=load))
        for kind in dict.fromkeys(k for k, _ in estimators):
            floors = [1e3 * est.smallest_deciding_budget_s for k, est in estimators if k == kind]
            rows.append(SimpleNamespace(floor=True, kind=kind, load=load, floor_ms=floors))
        if fifo:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    return rows


# -- the report's section: deadlines -------------------------------------------------------------------------
def off_core(row) -> np.ndarray:
    """Per solve of a deadline row: the thread was off its core without a context switch (none measured: False)."""
    off = getattr(row, "off_core", None)
    return np.zeros_like(row.preempted) if off is None else off


def disturbed(row) -> np.ndarray:
    """Per solve of a deadline row: preempted by another process, off its core (an interrupt, the hypervisor), or
    Python's collector ran (in the caller, before the solve holds it off): what no code of the solve decides."""
    return row.preempted | off_core(row) | row.collected


def cpu_past(row) -> np.ndarray:
    """Per solve of a deadline row: the thread's CPU time less the budget (ms; NaN: not measured).  The CPU time
    before the deadline is at most the budget, so this is at least the solver's own work after it: a late solve
    whose CPU time is within the budget was late because it was off its core (wall time less CPU time), not
    because it ran past."""
    cpu = getattr(row, "cpu_s", None)
    return np.full(row.overrun_ms.shape, np.nan) if cpu is None else np.asarray(cpu) * 1e3 - row.budget_ms


def all_overruns(rows) -> tuple[np.ndarray, np.ndarray]:
    """The overruns (ms) of every deadline solve, and of those not disturbed."""
    rows = [r for r in rows if hasattr(r, "overrun_ms")]
    return np.concatenate([r.overrun_ms for r in rows]), np.concatenate([r.overrun_ms[~disturbed(r)] for r in rows])


def _counts(rows) -> str:
    """Preempted / off its core / collector ran, over the solves of ``rows``."""
    return " / ".join(str(int(sum(np.sum(f(r)) for r in rows)))
                      for f in (lambda r: r.preempted, lambda r: off_core(r) & ~r.preempted,
                                lambda r: r.collected & ~r.preempted & ~off_core(r)))


def share_on_time(over) -> float:
    """The share (%) of the overruns ``over`` (ms) within the margin."""
    return 100.0 * float(np.mean(over <= DEADLINE_MARGIN_MS))


def worst_overrun(over) -> str:
    """The largest of the overruns ``over`` (ms), signed; a dash when there are none."""
    return f"{float(np.max(over)):+.3f}" if over.size else MISSING


def tail(over) -> str:
    """p99.9 and max of the overruns ``over`` (ms), signed; dashes when there are none (or not measured)."""
    over = over[~np.isnan(over)]
    if not over.size:
        return f"{MISSING} / {MISSING}"
    return f"{float(np.percentile(over, TAIL_QUANTILE)):+.3f} / {float(np.max(over)):+.3f}"


def late_solves(rows) -> list[list]:
    """The solves more than :data:`LATE_MS` past their deadline, per load the latest first (at most
    :data:`LATE_LISTED` per load), each with its lateness split: the time off its core (wall time less the
    thread's CPU time) and the CPU time past the budget (:func:`cpu_past`), and which of the two explains it."""
    lines = []
    for load in dict.fromkeys(getattr(r, "load", LOADS[0]) for r in rows):
        lines += _late([r for r in rows if getattr(r, "load", LOADS[0]) == load])
    return lines


def _late(rows) -> list[list]:
    late = []
    for r in rows:
        past = cpu_past(r)
        cpu = getattr(r, "cpu_s", None)
        for i in np.flatnonzero(r.overrun_ms > LATE_MS):
            off = MISSING if cpu is None else f"{r.elapsed_s[i] * 1e3 - cpu[i] * 1e3:.3f}"
            why = MISSING if np.isnan(past[i]) else \
                RAN_PAST if past[i] > LATE_MS else OFF_CORE
            late.append((float(r.overrun_ms[i]), [r.case, r.solver, f"{r.budget_ms:g}", getattr(r, "load", LOADS[0]),
                                                  f"{r.overrun_ms[i]:+.3f}", off,
                                                  MISSING if np.isnan(past[i]) else f"{past[i]:+.3f}", why]))
    return [line for _, line in sorted(late, key=lambda t: -t[0])[:LATE_LISTED]]


#: the deadline tables' column of the solves counted apart (:func:`disturbed`)
DISTURBED = "preempted / off core / collector"
#: ... and of the thread's CPU time past the budget (:func:`cpu_past`)
CPU_PAST = "p99.9 / max of CPU − budget, ms"


#: the columns of the machine's stalls, per load (:func:`stalls_cells`)
STALLS_HEAD = ["load", "probed s", f"stalls > {LATE_MS:g} ms", f"> {DEADLINE_MARGIN_MS:g} ms",
               "longest off its core ms", "longest on its core ms", "solves to their deadline",
               f"> {LATE_MS:g} ms late: expected from the stalls / solves",
               f"> {DEADLINE_MARGIN_MS:g} ms late: expected / solves"]


def stalls_cells(probe, rows) -> list:
    """A row of the stalls table: the load's probe (``probe.stalls``) and its cells' ``rows``.  The solves that ran
    to their deadline (ended no more than LATE_MS before it) are the ones a stall can make late; each is late by
    more than ``ms`` with the probability that a stall then has more than ``ms`` left (:meth:`Stalls.share_past`),
    so the stalls explain about that many of them, set beside the solves that were."""
    st = probe.stalls
    overrun = np.concatenate([r.overrun_ms for r in rows]) if rows else np.zeros(0)
    at_risk = int(np.sum(overrun >= -LATE_MS))

    def against(ms):
        return f"{at_risk * st.share_past(ms):.2g} / {int(np.sum(overrun > ms))}"
    return [probe.load, f"{st.seconds:.3g}", st.over(LATE_MS), st.over(DEADLINE_MARGIN_MS),
            fmt(st.longest_ms(on_core=False)), fmt(st.longest_ms(on_core=True)), at_risk,
            against(LATE_MS), against(DEADLINE_MARGIN_MS)]


def deadline_section(res, md_path) -> list[str]:
    """Per solver and load, p99.9 and max of (end - deadline) over every cell, with and without the disturbed
    solves; then each cell's, with its statuses."""
    floors = [r for r in res["deadline"] if getattr(r, "floor", False)]
    probes = [r for r in res["deadline"] if hasattr(r, "stalls")]
    rows = [r for r in res["deadline"] if hasattr(r, "overrun_ms")]

    def on_time(over):
        return pct(share_on_time(over), 4) if over.size else MISSING
    loads = list(dict.fromkeys(getattr(r, "load", LOADS[0]) for r in rows))
    per_solver = []
    for load in loads:
        for solver in dict.fromkeys(r.solver for r in rows):
            mine = [r for r in rows if r.solver == solver and getattr(r, "load", LOADS[0]) == load]
            over, calm = all_overruns(mine)
            per_solver.append([solver, load, len(over), tail(over), _counts(mine), tail(calm),
                               tail(np.concatenate([cpu_past(r) for r in mine]))])
    body = [[r.case, r.solver, f"{r.budget_ms:g}", getattr(r, "load", LOADS[0]), len(over), tail(over),
             _counts([r]), tail(calm), tail(cpu_past(r)), on_time(over),
             ", ".join(f"{k} {v}" for k, v in sorted(getattr(r, "statuses", {}).items()))]
            for r in rows for over, calm in [(r.overrun_ms, r.overrun_ms[~disturbed(r)])]]
    total, calm = all_overruns(rows)
    late = sorted({r.solver for r in rows if np.any(r.overrun_ms[~disturbed(r)] > DEADLINE_MARGIN_MS)})
    return md_blocks(
        "## Deadline honouring",
        prose("deadline", margin=DEADLINE_MARGIN_MS, stop_after=STOP_AFTER, stop_factor=f"{STOP_OVERRUN_FACTOR:g}",
              off_core_ms=f"{timing.OFF_CORE_S * 1e3:g}"),
        calm.size and prose("deadline", "overall", on_time=on_time(total), solves=total.size,
                            worst=worst_overrun(total), preempted=total.size - calm.size, calm_on_time=on_time(calm),
                            calm_worst=worst_overrun(calm)),
        late and ("Late undisturbed (the solver's code after its deadline, or a stall on its core that the thread's "
                  "CPU clock counts as its own: the machine's stalls below): " + ", ".join(f"`{x}`" for x in late)
                  + "."),
        probes and prose("deadline", "stalls", late_ms=LATE_MS, margin=DEADLINE_MARGIN_MS,
                         threshold_us=f"{stalls.THRESHOLD_S * 1e6:g}", off_core_ms=f"{timing.OFF_CORE_S * 1e3:g}"),
        probes and table(STALLS_HEAD, [stalls_cells(p, [r for r in rows if getattr(r, "load", LOADS[0]) == p.load])
                                       for p in probes]),
        floors and prose("deadline", "floor"),
        floors and table(["manipulator", "load", "Estimators", "smallest deciding budget ms: median", "max"],
                         [[f.kind, f.load, len(f.floor_ms), fmt(float(np.median(f.floor_ms))),
                           fmt(float(np.max(f.floor_ms)))] for f in floors]),
        table(["solver", "load", "solves", "p99.9 / max of end − deadline, ms", DISTURBED,
               "p99.9 / max, undisturbed", CPU_PAST], per_solver),
        table(["case", "solver", "budget ms", "load", "solves", "p99.9 / max ms", DISTURBED,
               "p99.9 / max ms, undisturbed", CPU_PAST, "within budget + margin", "statuses"], body),
        prose("deadline", "late", late_ms=LATE_MS, listed=LATE_LISTED),
        table(["case", "solver", "budget ms", "load", "end − deadline ms", "off its core ms", "CPU − budget ms",
               "late because"], late_solves(rows)) if late_solves(rows) else f"No solve ended more than {LATE_MS:g} "
                                                                         "ms after its deadline.",
        figure_link(res, "deadline", md_path, "deadline overruns"))
