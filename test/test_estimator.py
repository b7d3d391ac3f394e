"""Estimator: tracking along smooth trajectories, round trips on random
geometries, escalation to cold search, infeasible input, state kept."""
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from conftest import GENEROUS_BUDGET_S
from glpma_ros.errors import InputError
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.models import Hexapod66, Planar3RPR
from glpma_ros.models.rotations import rotation_from_vector
from glpma_ros.solvers.refine import polish
from glpma_tools.sim.trajectories import variables_along

# generous: what is computed, not speed, is under test here (the same result on a busy machine)
BUDGET_S = GENEROUS_BUDGET_S


def _track(model, est, truth):
    for k, x in enumerate(truth):
        e = est.estimate(model.inverse_kinematics(x))
        assert e.converged, (k, e.message)
        assert model.distance(e.x, x) < 1e-6, (k, model.distance(e.x, x))
        if k > 0:
            assert e.start == "warm", (k, e.start)
    return e


def test_rpr_tracking_1000_steps_stays_on_branch(rpr, rpr_solutions):
    x0 = rpr_solutions[0]
    truth = variables_along(rpr, x0, 1000, amplitude=2.0)
    est = Estimator(rpr, initial_pose=x0, time_budget_s=BUDGET_S)
    _track(rpr, est, truth)


def test_hexapod_tracking_1000_steps_stays_on_branch(hexapod, hex_published):
    x0, *_ = polish(hexapod, hex_published[7], hexapod.example_leg_lengths, np.random.default_rng(0))
    truth = variables_along(hexapod, x0, 1000)
    est = Estimator(hexapod, initial_pose=x0, time_budget_s=BUDGET_S)
    _track(hexapod, est, truth)


def test_both_rpr_branches_are_tracked_separately(rpr, rpr_solutions):
    """Same legs, two assembly modes: each estimator stays on its own."""
    for x0 in rpr_solutions:
        est = Estimator(rpr, initial_pose=x0, time_budget_s=BUDGET_S)
        e = est.estimate(rpr.example_leg_lengths)
        assert e.converged and rpr.distance(e.x, x0) < 1e-6


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(["rpr", "hexapod"]))
def test_round_trip_random_geometry_and_pose(seed, kind):
    """Inverse kinematics, then a warm-started solve, recovers the pose to 1e-6 of the scale."""
    rng = np.random.default_rng(seed)
    if kind == "rpr":
        base = rng.uniform(-300, 300, (3, 2))
        platform = rng.uniform(-60, 60, (3, 2))
        e1, e2 = platform[1] - platform[0], platform[2] - platform[0]
        assume(abs(e1[0] * e2[1] - e1[1] * e2[0]) > 400)
        model = Planar3RPR(base, platform)
        x = np.array([*rng.uniform(-100, 100, 2), rng.uniform(-np.pi, np.pi)])
    else:
        base = rng.uniform(-600, 600, (6, 3)) * [1, 1, 0.1]
        platform = rng.uniform(-300, 300, (6, 3)) * [1, 1, 0.1]
        assume(np.linalg.norm(np.cross(platform[1] - platform[0], platform[2] - platform[0])) > 2e4)
        model = Hexapod66(base, platform)
        x = model.pose_variables((rotation_from_vector(rng.normal(0, 0.3, 3)),
                                  np.array([*rng.uniform(-100, 100, 2), rng.uniform(600, 1200)])))
    legs = model.inverse_kinematics(x)
    assume(model.conditioning(x, legs) > 1e-3)  # away from singularities
    near = x + model.spread_vector(1e-3 * model.scale) * rng.standard_normal(model.n_vars)
    est = Estimator(model, initial_pose=near, time_budget_s=BUDGET_S)
    e = est.estimate(legs)
    assert e.converged, e.message
    assert model.distance(e.x, x) < 1e-6 * model.scale


def test_cold_estimate_without_initial_pose(rpr):
    est = Estimator(rpr, time_budget_s=BUDGET_S)
    e = est.estimate(rpr.example_leg_lengths)
    assert e.converged and e.start == "cold"
    assert est.has_warm_state


def test_infeasible_legs_no_solution_and_state_kept(rpr, rpr_solutions):
    x0 = rpr_solutions[0]
    est = Estimator(rpr, initial_pose=x0, time_budget_s=BUDGET_S)
    e = est.estimate([1.0, 1.0, 1.0])  # legs far too short to reach the platform
    assert e.status == "no_solution" and e.pose is None
    assert np.all(np.isfinite([e.fitness]))
    np.testing.assert_array_equal(est.last_x, x0)
    e = est.estimate(rpr.example_leg_lengths)
    assert e.converged and e.start == "warm" and rpr.distance(e.x, x0) < 1e-6


def test_bad_input_raises_and_keeps_state(rpr, rpr_solutions):
    est = Estimator(rpr, initial_pose=rpr_solutions[1], time_budget_s=BUDGET_S)
    for bad in ([1.0, 2.0], [np.nan, 1, 1], [1, 1, -1], [np.inf, 1, 1]):
        with pytest.raises(InputError):
            est.estimate(bad)
    np.testing.assert_array_equal(est.last_x, rpr_solutions[1])


def test_large_jump_recovers_with_escalation(rpr, rpr_solutions):
    """Legs that jump far from the previous ones: warm fails, the estimator escalates."""
    est = Estimator(rpr, initial_pose=rpr_solutions[0], time_budget_s=BUDGET_S)
    target = np.array([150.0, 30.0, 2.5])
    e = est.estimate(rpr.inverse_kinematics(target))
    assert e.converged
    np.testing.assert_allclose(rpr.inverse_kinematics(e.x), rpr.inverse_kinematics(target), atol=1e-9)


def test_switch_solver_keeps_state(rpr, rpr_solutions):
    est = Estimator(rpr, initial_pose=rpr_solutions[0], time_budget_s=BUDGET_S)
    for name in ("g3pcx", "rcga", "glpma"):
        est.set_solver(name)
        e = est.estimate(rpr.example_leg_lengths)
        assert e.converged and e.solver == name and rpr.distance(e.x, rpr_solutions[0]) < 1e-6
    with pytest.raises(InputError, match="unknown solver"):
        est.set_solver("newton")


def test_readings_in_one_call_give_what_the_long_way_gives(rpr, rpr_solutions):
    """``estimate_readings`` (the node's everyday input: readings converted and solved warm in one compiled
    call) returns the legs and the estimate that converting the readings and ``estimate`` give, and declines
    (None, nothing done) where the long way must name the problem or search."""
    mm = 1e-3                                   # readings in metres, the config in millimetres
    offsets = np.array([0.5, -0.25, 1.0])       # leg_offsets: |B - A| = reading + offset
    x0 = np.asarray(rpr_solutions[0], dtype=float)
    one = Estimator(rpr, time_budget_s=BUDGET_S, initial_pose=x0, seed=0)
    other = Estimator(rpr, time_budget_s=BUDGET_S, initial_pose=x0, seed=0)
    band = (1.0, 1000.0)
    for k, x in enumerate(variables_along(rpr, x0, 40)):
        legs = rpr.inverse_kinematics(x)
        readings = tuple(((legs - offsets) * mm).tolist())
        got = one.estimate_readings(readings, mm, *band, offsets)
        assert got is not None, k
        got_legs, got_e = got
        want_e = other.estimate(np.array(readings) / mm + offsets)
        # the same numbers through the same compiled kernel: equal up to the last bit of the division
        np.testing.assert_allclose(got_legs, legs, rtol=1e-12)
        assert got_e.status == want_e.status and got_e.start == want_e.start == "warm", (k, got_e.message)
        assert rpr.distance(got_e.x, want_e.x) < 1e-9 * rpr.scale, k
        assert rpr.distance(one.last_x, other.last_x) < 1e-9 * rpr.scale, k
    state = one.last_x.copy()
    for bad in ((0.1, 0.1), (math.nan, 0.1, 0.1), (5.0, 0.1, 0.1), ("a", 0.1, 0.1)):
        assert one.estimate_readings(bad, mm, *band, offsets) is None, bad
    np.testing.assert_array_equal(one.last_x, state)          # declined: nothing done
    cold = Estimator(rpr, time_budget_s=BUDGET_S, seed=0)      # no warm start yet
    assert cold.estimate_readings(readings, mm, *band, offsets) is None
    off = Estimator(rpr, time_budget_s=BUDGET_S, initial_pose=x0, seed=0, polish=False)
    assert off.estimate_readings(readings, mm, *band, offsets) is None
