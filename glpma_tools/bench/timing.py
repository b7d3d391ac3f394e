"""The bench's deadline experiment (:func:`deadlines`), on the timed calls every tool shares
(:mod:`glpma_tools.timing`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glpma_tools import timing
from glpma_tools.stats import distribution
from glpma_tools.tables import MISSING, fmt, table
from glpma_tools.timing import DEADLINE_MARGIN_MS, STOP_AFTER, STOP_OVERRUN_FACTOR

from .report import figure_link, md_blocks, prose

#: the bench's deadline cells are small: a short warm-up is enough
DEADLINE_WARM_UP_QUIET = 3
DEADLINE_WARM_UP_MAX_CALLS = 30


@dataclass
class DeadlineRow(timing.TimedCalls):
    """The timed calls of one case, solver and budget."""

    case: str = ""
    solver: str = ""
    short: str = ""

    @property
    def label(self):
        return f"{self.short} | {self.solver}"


def _row(case, solver, b, short, call, n, progress) -> DeadlineRow:
    timing.warm_up(call, b, DEADLINE_WARM_UP_QUIET, DEADLINE_WARM_UP_MAX_CALLS)
    calls = timing.timed_calls(call, n, b, f"deadline {short} {solver} {b:g} ms", progress)
    return DeadlineRow(**{**vars(calls), "results": []}, case=case, solver=solver, short=short)


def deadlines(scenarios, budgets_ms, n, progress, names=None) -> list[DeadlineRow]:
    """The bench's deadline experiment: cold searches that cannot converge, stopped only by their time
    budget (every registered solver, and the Estimator as the node runs it)."""
    from glpma_ros import solvers
    from glpma_ros.estimator import Estimator
    rows = []
    names = list(names or solvers.SOLVERS)
    for sc in scenarios:
        model = sc.model
        infeasible = timing.infeasible_legs(model)
        cases = [(f"{sc.label}, infeasible legs, default (polish)", f"{sc.label} infeasible", infeasible, True)]
        if sc.key == "hexapod":
            cases.insert(0, (f"{sc.label}, feasible legs, pure (cannot converge in ms)", f"{sc.label} pure",
                             sc.legs, False))
        for case, short, legs, polish in cases:
            for solver in names:
                for b in budgets_ms:
                    def call(seed, solver=solver, legs=legs, polish=polish, b=b, model=model):
                        solvers.solve(solver, model, legs, rng=seed, polish=polish, budget_s=b / 1e3,
                                      max_evals=timing.NO_CAP)
                    rows.append(_row(case, solver, b, short, call, n, progress))
        # the estimator, cold, on legs without a solution: every stage runs until the deadline
        case = f"{sc.label}, infeasible legs, Estimator (GLPMA, cold, its default evaluation cap)"
        for b in budgets_ms:
            est = Estimator(model, time_budget_s=b / 1e3)

            def call(_, est=est, infeasible=infeasible):
                est.reset()
                est.estimate(infeasible)
            rows.append(_row(case, "Estimator", b, f"{sc.label} infeasible, cold", call, n, progress))
    return rows


# -- the report's sections ----------------------------------------------------------------------------
def all_overruns(rows) -> tuple[np.ndarray, np.ndarray]:
    """The overruns (ms) of every deadline solve, and of those not preempted."""
    return np.concatenate([r.overrun_ms for r in rows]), np.concatenate([r.overrun_ms[~r.preempted] for r in rows])


def share_on_time(over) -> float:
    """The share (%) of the overruns ``over`` (ms) within the margin."""
    return 100.0 * float(np.mean(over <= DEADLINE_MARGIN_MS))


def worst_overrun(over) -> str:
    return f"{float(np.max(over)):+.3f}"


def deadline_section(res, md_path) -> list[str]:
    rows = res["deadline"]

    def on_time(over):
        return fmt(share_on_time(over), 4) + " %" if over.size else MISSING
    body = [[r.case, r.solver, f"{r.budget_ms:g}", f"{len(over)} (stopped)" if r.stopped_early else len(over),
             on_time(over), fmt(distribution(r.elapsed_s, 1e3)["p99"]), worst_overrun(over), int(np.sum(r.preempted)),
             on_time(calm), worst_overrun(calm) if calm.size else MISSING]
            for r in rows for over, calm in [(r.overrun_ms, r.overrun_ms[~r.preempted])]]
    total, calm = all_overruns(rows)
    late = sorted({r.solver for r in rows if np.any(r.overrun_ms[~r.preempted] > DEADLINE_MARGIN_MS)})
    return md_blocks(
        "## Deadline honouring",
        prose("deadline", margin=DEADLINE_MARGIN_MS, stop_after=STOP_AFTER, stop_factor=f"{STOP_OVERRUN_FACTOR:g}"),
        calm.size and f"Overall: {on_time(total)} of {total.size} solves on time, worst overrun {worst_overrun(total)} ms; "
        f"{total.size - calm.size} solves were preempted by other processes, and without them {on_time(calm)} are "
        f"on time, worst overrun {worst_overrun(calm)} ms.",
        late and "Late without preemption (the solver itself overran): " + ", ".join(f"`{x}`" for x in late) + ".",
        table(["case", "solver", "budget ms", "solves", "on time", "p99 elapsed ms", "worst overrun ms", "preempted",
               "on time, not preempted", "worst overrun, not preempted"], body),
        figure_link(res, "deadline", md_path, "deadline overruns"))
