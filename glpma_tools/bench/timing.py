"""The bench's deadline experiment (:func:`deadlines`), on the timed calls every tool shares
(:mod:`glpma_tools.timing`)."""
from __future__ import annotations

from dataclasses import dataclass

from glpma_tools import timing

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
