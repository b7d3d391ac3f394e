"""Statuses from work, not from the clock: the same legs get the same status whether nothing of the
search fitted in the budget (budget 0, what a very busy machine gives) or all of it did (seconds);
only ``budget_exhausted`` / ``max_evals`` say that a limit ran out.  No wall-clock assertion."""
import math

import numpy as np
import pytest

from glpma_ros.estimation.estimator import Estimator
from glpma_ros.models.hexapod_66 import rotation_from_vector

#: budgets from "nothing fits" to "everything fits" (seconds)
BUDGETS = (0.0, 0.005, 0.05, 5.0)


def _statuses(model, legs, warm=None, budgets=BUDGETS, seeds=range(3), **kw):
    return {Estimator(model, time_budget_s=b, seed=s, initial_pose=warm, **kw).estimate(legs).status
            for b in budgets for s in seeds}


@pytest.mark.parametrize("warm", [False, True])
def test_seed_rpr_statuses_do_not_depend_on_the_budget(rpr, rpr_solutions, warm):
    start = rpr_solutions[0] if warm else None
    assert _statuses(rpr, [60.0, 60.0, 60.0], start) == {"no_solution"}
    assert _statuses(rpr, [100.0, 120.0, 150.0], start) == {"converged"}
    for legs in ([1.0, 1.0, 1.0], [10.0, 300.0, 10.0], [400.0, 400.0, 400.0]):
        assert _statuses(rpr, legs, start) == {"no_solution"}, legs
    assert _statuses(rpr, [100.0, 120.0, 300.0], start) == {"near_singular"}


@pytest.mark.parametrize("warm", [False, True])
def test_hexapod_statuses_do_not_depend_on_the_budget(hexapod, hex_published, warm):
    start = hex_published[10] if warm else None
    kw = dict(budgets=(0.0, 0.01, 2.0), seeds=range(2))
    assert _statuses(hexapod, [100.0] * 6, start, **kw) == {"no_solution"}
    assert _statuses(hexapod, [1250.0] * 5 + [4000.0], start, **kw) == {"no_solution"}
    assert _statuses(hexapod, [1250.0] * 6, start, **kw) == {"converged"}


def test_feasible_legs_are_never_no_solution_even_with_no_budget(rpr, hexapod):
    """Legs of random poses: converged with a zero budget (the probe finds an assembly)."""
    rng = np.random.default_rng(1)
    for k in range(60):
        x = np.array([*rng.uniform(0, 200, 2), rng.uniform(-math.pi, math.pi)])
        e = Estimator(rpr, time_budget_s=0.0, seed=k).estimate(rpr.inverse_kinematics(x))
        assert e.converged, (x, e.message)
    for k in range(12):
        x = hexapod.pose_variables((rotation_from_vector(rng.normal(0, 0.3, 3)),
                                    np.array([*rng.uniform(-200, 200, 2), rng.uniform(600, 1100)])))
        e = Estimator(hexapod, time_budget_s=0.0, seed=k).estimate(hexapod.inverse_kinematics(x))
        assert e.converged, (x, e.message)


def test_without_the_refinement_the_limits_say_what_ran_out(rpr):
    """``polish=False`` (the papers' setting): the search alone must reach the tolerance; when it does
    not, the status names the limit, or ``no_solution`` for legs that have no assembly."""
    legs = [100.0, 120.0, 150.0]
    e = Estimator(rpr, time_budget_s=0.0, polish=False).estimate(legs)
    assert e.status == "budget_exhausted" and e.pose is None
    e = Estimator(rpr, time_budget_s=60.0, polish=False, max_evals=150).estimate(legs)
    assert e.status == "max_evals" and e.pose is None
    e = Estimator(rpr, time_budget_s=60.0, polish=False).estimate(legs)
    assert e.converged and e.fitness < 1e-20
    assert Estimator(rpr, time_budget_s=0.0, polish=False).estimate([60.0, 60.0, 60.0]).status == "no_solution"


def test_a_rejected_input_keeps_the_warm_state(rpr, rpr_solutions):
    est = Estimator(rpr, initial_pose=rpr_solutions[0], time_budget_s=0.0)
    before = est.last_x.copy()
    assert est.estimate([60.0, 60.0, 60.0]).status == "no_solution"
    np.testing.assert_array_equal(est.last_x, before)
    e = est.estimate(rpr.example_leg_lengths)
    assert e.converged and e.start == "warm" and rpr.distance(e.x, before) < 1e-9
