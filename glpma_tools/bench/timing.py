"""The bench's deadline experiment (:func:`deadlines`) and its section, on the timed calls every tool shares
(:mod:`glpma_tools.timing`).  A row (a ``SimpleNamespace``): ``case``, ``solver``, ``label`` (the figure's: the
case in short and the solver) and the fields of its :class:`~glpma_tools.timing.TimedCalls`, with ``overrun_ms``."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from glpma_tools import timing
from glpma_tools.stats import distribution
from glpma_tools.tables import MISSING, fmt, table
from glpma_tools.timing import DEADLINE_MARGIN_MS, NO_CAP, STOP_AFTER, STOP_OVERRUN_FACTOR

from .report import figure_link, md_blocks, pct, prose

#: the bench's deadline cells are small: a short warm-up is enough
DEADLINE_WARM_UP_QUIET = 3
DEADLINE_WARM_UP_MAX_CALLS = 30


def deadlines(scenarios, budgets_ms, n, progress, names=None) -> list[SimpleNamespace]:
    """The bench's deadline experiment: cold searches that cannot converge, stopped only by their time
    budget (every registered solver, and the Estimator as the node runs it, cold: every stage runs until the
    deadline)."""
    from glpma_ros import solvers
    from glpma_ros.estimator import Estimator

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
        timing.warm_up(call, b, DEADLINE_WARM_UP_QUIET, DEADLINE_WARM_UP_MAX_CALLS)
        calls = timing.timed_calls(call, n, b, f"deadline {short} {solver} {b:g} ms", progress)
        rows.append(SimpleNamespace(**{**vars(calls), "results": []}, overrun_ms=calls.overrun_ms, case=case,
                                    solver=solver, label=f"{short} | {solver}"))
    return rows


# -- the report's section -----------------------------------------------------------------------------
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
