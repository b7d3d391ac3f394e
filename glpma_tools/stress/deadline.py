"""Deadlines in process: :class:`~glpma_ros.estimation.estimator.Estimator` solves on legs without a real
assembly that only its search and probe tell (not the loop bounds of a pair of legs) and without an
evaluation cap, so that only the deadline or the deciding work stops each one -- cold (state
reset before each solve) and warm (a warm state that the failures keep, so that the warm, widened
and cold stages all run).  The timed calls are the ones every measuring tool shares (:mod:`glpma_tools.timing`)."""
from __future__ import annotations

from collections import Counter

from glpma_ros.estimation.estimator import Estimator
from glpma_tools.stats import distribution
from glpma_tools.timing import NO_CAP, probed_infeasible_legs, timed_calls, warm_up

DEADLINE_BUDGETS_MS = (1.0, 2.0, 5.0)
CASES = ("cold", "warm")


def deadline_cell(model, case: str, budget_ms: float, n: int, seed_x=None) -> dict:
    """``n`` timed solves of one case and budget, after a warm-up until the solves run on time."""
    legs = probed_infeasible_legs(model)
    est = Estimator(model, time_budget_s=budget_ms * 1e-3, initial_pose=seed_x if case == "warm" else None,
                    max_evals=NO_CAP)

    def call(_):
        if case == "cold":
            est.reset()
        return est.estimate(legs).status

    warm_up(call, budget_ms)
    calls = timed_calls(call, n, budget_ms, stop_early=False)
    elapsed = distribution(calls.elapsed_s, 1e3)
    return {"case": case, "budget_ms": budget_ms, "solves": n, "on_time_pct": calls.on_time_pct(),
            "elapsed_p50_ms": elapsed["p50"], "elapsed_p99_ms": elapsed["p99"],
            "worst_overrun_ms": calls.worst_overrun_ms(), "preempted": int(calls.preempted.sum()),
            "gc": int(calls.collected.sum()), "on_time_undisturbed_pct": calls.on_time_pct(undisturbed=True),
            "worst_overrun_undisturbed_ms": calls.worst_overrun_ms(undisturbed=True),
            "statuses": dict(Counter(calls.results))}


def deadlines(model, budgets_ms=DEADLINE_BUDGETS_MS, n: int = 10_000, seed_x=None, say=None) -> list[dict]:
    """:func:`deadline_cell` for every case and budget; ``seed_x``: the warm case's initial pose."""
    rows = []
    for case in CASES:
        for b in budgets_ms:
            if say:
                say(f"deadline: {n} Estimator solves, {case}, {b:g} ms")
            rows.append(deadline_cell(model, case, b, n, seed_x))
    return rows
