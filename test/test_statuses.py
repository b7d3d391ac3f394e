"""Statuses from work, not from the clock: above the smallest budget at which the deciding work fits
(README, "Deadlines": about a millisecond on this machine) the same legs get the same status whether
little of the search fitted in the budget or all of it did (seconds); only ``budget_exhausted`` /
``max_evals`` say that a limit ran out.  With no budget at all, no work is done: the legs get
``no_solution`` when the loop bounds of a pair of legs tell it from the legs alone, else
``budget_exhausted``.  No wall-clock assertion."""
import math

import numpy as np
import pytest

from glpma_ros.estimation.estimator import Estimator
from glpma_ros.models.hexapod_66 import rotation_from_vector
from glpma_ros.runtime import precompile

#: budgets from "the deciding work fits, with room for a busy machine" to "everything fits" (seconds)
BUDGETS = (0.2, 5.0)
#: legs with no assembly that the loop bounds tell, and legs with none that only the probe tells
RPR_TOLD = ([60.0, 60.0, 60.0], [1.0, 1.0, 1.0], [10.0, 300.0, 10.0])
RPR_PROBED = [400.0, 400.0, 400.0]


@pytest.fixture(scope="module", autouse=True)
def loaded(rpr, hexapod):
    """The one-time load of the compiled solvers before the first timed solve, as the node and the CLI do
    (it is not part of any solve's budget)."""
    for model in (rpr, hexapod):
        precompile.exercise(model, "glpma")


def _statuses(model, legs, warm=None, budgets=BUDGETS, seeds=range(3), **kw):
    return {Estimator(model, time_budget_s=b, seed=s, initial_pose=warm, **kw).estimate(legs).status
            for b in budgets for s in seeds}


@pytest.mark.parametrize("warm", [False, True])
def test_seed_rpr_statuses_do_not_depend_on_the_budget(rpr, rpr_solutions, warm):
    start = rpr_solutions[0] if warm else None
    assert _statuses(rpr, [100.0, 120.0, 150.0], start) == {"converged"}
    for legs in (*RPR_TOLD, RPR_PROBED):
        assert _statuses(rpr, legs, start) == {"no_solution"}, legs
    assert _statuses(rpr, [100.0, 120.0, 300.0], start) == {"near_singular"}


@pytest.mark.parametrize("warm", [False, True])
def test_with_no_budget_only_the_legs_alone_decide(rpr, hexapod, rpr_solutions, warm):
    start = rpr_solutions[0] if warm else None
    for legs in RPR_TOLD:
        e = Estimator(rpr, time_budget_s=0.0, initial_pose=start).estimate(legs)
        assert e.status == "no_solution" and e.evaluations == 0 and "no real assembly: legs" in e.message, legs
    for legs in (RPR_PROBED, [100.0, 120.0, 150.0], [100.0, 120.0, 300.0]):
        e = Estimator(rpr, time_budget_s=0.0, initial_pose=start).estimate(legs)
        assert e.status == "budget_exhausted" and e.evaluations == 0 and e.pose is None, legs
    assert Estimator(hexapod, time_budget_s=0.0).estimate([100.0] * 6).status == "no_solution"
    assert Estimator(hexapod, time_budget_s=0.0).estimate([1250.0] * 6).status == "budget_exhausted"


@pytest.mark.parametrize("warm", [False, True])
def test_hexapod_statuses_do_not_depend_on_the_budget(hexapod, hex_published, warm):
    start = hex_published[10] if warm else None
    kw = dict(seeds=range(2))
    assert _statuses(hexapod, [100.0] * 6, start, **kw) == {"no_solution"}
    assert _statuses(hexapod, [1250.0] * 5 + [4000.0], start, **kw) == {"no_solution"}
    assert _statuses(hexapod, [1250.0] * 6, start, **kw) == {"converged"}
    assert _statuses(hexapod, [900.0, 1600.0] * 3, start, **kw) == {"no_solution"}      # told by the probe


def test_feasible_legs_are_never_no_solution(rpr, hexapod):
    """Legs of random poses: converged with a budget the deciding work fits in (the probe finds an
    assembly whatever fitted of the search), ``budget_exhausted`` with none."""
    rng = np.random.default_rng(1)
    for k in range(60):
        x = np.array([*rng.uniform(0, 200, 2), rng.uniform(-math.pi, math.pi)])
        legs = rpr.inverse_kinematics(x)
        e = Estimator(rpr, time_budget_s=BUDGETS[0], seed=k).estimate(legs)
        assert e.converged, (x, e.message)
        assert Estimator(rpr, time_budget_s=0.0, seed=k).estimate(legs).status == "budget_exhausted"
    for k in range(12):
        x = hexapod.pose_variables((rotation_from_vector(rng.normal(0, 0.3, 3)),
                                    np.array([*rng.uniform(-200, 200, 2), rng.uniform(600, 1100)])))
        e = Estimator(hexapod, time_budget_s=BUDGETS[0], seed=k).estimate(hexapod.inverse_kinematics(x))
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
    est = Estimator(rpr, initial_pose=rpr_solutions[0], time_budget_s=BUDGETS[0])
    before = est.last_x.copy()
    assert est.estimate([60.0, 60.0, 60.0]).status == "no_solution"
    np.testing.assert_array_equal(est.last_x, before)
    e = est.estimate(rpr.example_leg_lengths)
    assert e.converged and e.start == "warm" and rpr.distance(e.x, before) < 1e-9
