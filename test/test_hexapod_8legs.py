"""The shipped 8-leg hexapod (config/hexapod_8legs.yaml: Rolland's 6-6 plus two redundant legs): its
example legs and known solution, and what one and two redundant legs can do on a cold start -- one
spare measurement detects a faulty leg, two isolate it from the input alone.  Every solve has an
evaluation cap and a generous budget: the statuses come from the work done."""
import numpy as np
import pytest
import yaml

from conftest import CONFIG, GENEROUS_BUDGET_S
from glpma_ros.config import load_manipulator
from glpma_ros.estimation.estimator import STATUS_CONVERGED, STATUS_INCONSISTENT, Estimator

#: evaluation cap of each search stage
MAX_EVALS = 20_000
#: the example legs are written with 9 decimals (mm): they match the inverse kinematics of the known
#: solution to their rounding (5e-10) and the solver variables' own 9 decimals moved through the legs
DECIMALS_MM = 1e-8
#: a cold solve of the example legs finds the known pose to round-off of the solve (relative to the scale)
SAME_POSE_RTOL = 1e-9
#: leg noise of the fault tests: the default leg_noise_std (1e-5 m) in the config's mm
NOISE_MM = 0.01
#: the fault isolated from a cold start: 10 mm (1000 sigma) on one leg
FAULT_MM = 10.0
#: the pose from the other legs is within the noise's effect of the true one (mm), not the fault's
NOISE_EFFECT_MM = 0.5
#: ... and explains the other legs to their noise: every residual within 5 sigma
NOISE_RESIDUAL_MM = 5 * NOISE_MM
#: the base joints are coplanar to 0.4 mm: the pose's mirror image through the base plane fits the legs
#: as well (a cold start cannot tell the two apart), and the mirrored joints are that far from exact
MIRROR_MM = 1.0


def _mirror(model, x):
    """Solver variables (three platform joints in the base frame) mirrored through the base joints' plane."""
    z0 = float(np.mean(model.base[:, 2]))
    m = np.array(x, dtype=float).reshape(3, 3)
    m[:, 2] = 2.0 * z0 - m[:, 2]
    return m.ravel()


def _load(name):
    doc = yaml.safe_load((CONFIG / f"{name}.yaml").read_text())
    return load_manipulator(CONFIG / f"{name}.yaml"), np.array(doc["published_solutions"][0])


@pytest.fixture(scope="module")
def eight():
    return _load("hexapod_8legs")


def test_eight_legs_extend_the_seven_leg_config(eight):
    model, x = eight
    seven, x7 = _load("hexapod_7legs")
    assert model.n_legs == 8 and model.redundancy == 2
    assert np.array_equal(model.base[:7], seven.base) and np.array_equal(model.platform[:7], seven.platform)
    assert np.array_equal(x, x7)


def test_example_legs_are_those_of_the_known_solution(eight):
    model, x = eight
    assert np.allclose(model.inverse_kinematics(x), model.example_leg_lengths, rtol=0, atol=DECIMALS_MM)


@pytest.mark.parametrize("start", ["warm", "cold"])
def test_the_example_legs_solve_to_the_known_solution(eight, start):
    """Warm from the known solution and cold: two redundant legs leave one pose that fits all eight."""
    model, x = eight
    est = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS,
                    initial_pose=x if start == "warm" else None)
    e = est.estimate(model.example_leg_lengths)
    assert e.status == STATUS_CONVERGED and e.start == start
    assert model.distance(e.x, x) <= SAME_POSE_RTOL * model.scale


@pytest.mark.parametrize("leg", range(8))
def test_two_redundant_legs_isolate_a_faulty_leg_on_a_cold_start(eight, leg):
    """No previous pose: the input alone names the faulty leg, leaves it out and gives the pose of the
    other seven: it explains them to their noise, and it is the true pose (within the noise's effect)
    or its mirror image through the base plane, which fits every leg as well."""
    model, x = eight
    legs = model.example_leg_lengths + np.random.default_rng(leg).normal(0.0, NOISE_MM, model.n_legs)
    legs[leg] += FAULT_MM
    e = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS).estimate(legs)
    assert e.status == STATUS_INCONSISTENT and e.start == "cold"
    assert e.suspect_leg == e.excluded_leg == leg and e.publishable, e.message
    others = np.delete(model.inverse_kinematics(e.x) - legs, leg)
    assert np.max(np.abs(others)) <= NOISE_RESIDUAL_MM
    assert model.distance(e.x, x) <= NOISE_EFFECT_MM or model.distance(e.x, _mirror(model, x)) <= MIRROR_MM


def test_one_redundant_leg_detects_a_fault_but_needs_the_history_to_isolate_it():
    """The 7-leg hexapod, cold: the fault is detected (inconsistent_legs) and no leg is named, with the
    reason; warm (the previous pose known) the same input isolates it."""
    model, x = _load("hexapod_7legs")
    legs = model.example_leg_lengths + np.random.default_rng(1).normal(0.0, NOISE_MM, model.n_legs)
    legs[3] += FAULT_MM
    cold = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS).estimate(legs)
    assert cold.status == STATUS_INCONSISTENT and cold.excluded_leg is None and not cold.publishable
    assert "one redundant leg and no previous pose" in cold.message
    warm = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS, initial_pose=x).estimate(legs)
    assert warm.status == STATUS_INCONSISTENT and warm.suspect_leg == warm.excluded_leg == 3, warm.message
    assert model.distance(warm.x, x) <= NOISE_EFFECT_MM
