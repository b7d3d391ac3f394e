"""Property-based fuzzing of the node's service (in process, no DDS): arbitrary arrays of leg
lengths -- any length, NaN, inf, huge, tiny, negative, zero, denormal, empty, other dtypes and
shapes, and near-valid legs that do converge -- into :meth:`FkService.handle`.

For every input: no exception; either a pose or a one-line reason, never both; the reason names
the cause (wrong count, not finite, not positive, or the estimator's status); a pose only for an
input that converged, finite, unit quaternion, the input's stamp; the warm-start state unchanged
by a rejection and moved to the estimate by a success; the counters add up.  The mixed fuzzing's
number of cases per kind is printed (``-s``), not asserted (it depends on Hypothesis' version and
seed); every kind is covered on purpose by a strategy of its own (test_every_kind_of_input)."""
import math
from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from conftest import GENEROUS_BUDGET_MS, RPR_YAML
from glpma_ros.estimation.estimator import STATUS_BUDGET, STATUS_MAX_EVALS, STATUS_NEAR_SINGULAR, STATUS_NO_SOLUTION
from glpma_ros.node.service import FkService
from glpma_ros.solvers.lm import LEG_RTOL

SEED_X = [52.860968946, 84.886500470, math.radians(-33.461467708)]
SEED_LEGS_M = np.array([0.100, 0.120, 0.150])
STATUSES = (STATUS_NO_SOLUTION, STATUS_BUDGET, STATUS_NEAR_SINGULAR, STATUS_MAX_EVALS)

CASES: Counter = Counter()
#: each input's outcome is decided by the work done, the same on a busy machine
GENEROUS = {"time_budget_ms": GENEROUS_BUDGET_MS}

special = st.sampled_from([0.0, -0.0, 5e-324, 1e-320, 2.2250738585072014e-308, 1e-300, 1e-12, 1e-9,
                           1e300, 1.7976931348623157e308, 1e306, -1.0, -1e-300, -math.inf, math.inf, math.nan,
                           0.05, 0.1, 0.12, 0.15, 0.25, 1.0, 1e3])
anything = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)
plausible = st.floats(min_value=0.01, max_value=0.4)
element = st.one_of(anything, special, plausible)

# near the seed legs: most of these converge, some are past the workspace (no_solution)
near_valid = st.lists(st.floats(min_value=-0.05, max_value=0.05), min_size=3, max_size=3).map(
    lambda d: list(SEED_LEGS_M * (1.0 + np.asarray(d))))
float_lists = st.lists(element, min_size=0, max_size=9)
numpy_arrays = hnp.arrays(dtype=st.sampled_from([np.float64, np.float32, np.float16, np.int64, np.int8]),
                          shape=hnp.array_shapes(min_dims=0, max_dims=2, min_side=0, max_side=4))
legs_inputs = st.one_of(float_lists, near_valid, near_valid, numpy_arrays,
                        st.tuples(element, element, element).map(list))


@pytest.fixture(scope="module")
def service():
    svc = FkService({"manipulator_config": str(RPR_YAML), "initial_pose": SEED_X, **GENEROUS})
    svc.warm_up(solvers=("glpma",))          # compiled before the time budgets count
    service_limits[0] = svc.model.leg_limits
    return svc


def expected_rejection(legs, metres_per_unit: float):
    """The validation failure the input must be rejected for (``None``: the estimator decides)."""
    arr = np.asarray(legs, dtype=float).reshape(-1)
    if arr.size != 3:
        return "expected 3 leg lengths"
    with np.errstate(over="ignore", invalid="ignore"):
        converted = arr / metres_per_unit           # the service works in the config's unit
    if not np.all(np.isfinite(arr)):
        return "leg lengths must be finite"
    if not np.all(np.isfinite(converted)):          # finite in metres, beyond float range in mm
        return "leg lengths too large"
    if np.any(converted <= 0.0):
        return "leg lengths must be positive"
    limits = service_limits[0]
    if limits is not None and (np.any(converted < limits[0]) or np.any(converted > limits[1])):
        # outside the config's leg_limits: a unit hint, or the limits named
        return ("leg lengths look like", "leg lengths outside the configured limits")
    return None


#: the service's leg_limits (config unit), set by the fixture
service_limits = [None]


def _copy(x):
    return None if x is None else np.array(x, dtype=float, copy=True)


stamps = st.integers(min_value=0, max_value=2**63 - 1)
#: one strategy per kind of input, so that each kind is tried on purpose, whatever the mixed draws do
KINDS = {
    "expected 3 leg lengths": st.one_of(st.lists(plausible, min_size=0, max_size=2),
                                        st.lists(plausible, min_size=4, max_size=9)),
    "leg lengths must be finite": st.tuples(st.sampled_from([math.nan, math.inf, -math.inf]), plausible,
                                            plausible, st.permutations(range(3))).map(
        lambda t: [t[:3][i] for i in t[3]]),
    "leg lengths must be positive": st.tuples(st.sampled_from([0.0, -0.0, -1e-300, -0.1, -1e300]),
                                              plausible, plausible, st.permutations(range(3))).map(
        lambda t: [t[:3][i] for i in t[3]]),
    # a few per cent from the seed legs: the seed's assembly mode moves a little, a converged pose
    "solved": st.lists(st.floats(min_value=-0.01, max_value=0.01), min_size=3, max_size=3).map(
        lambda d: list(SEED_LEGS_M * (1.0 + np.asarray(d)))),
}
#: examples per kind
KIND_EXAMPLES = 50


@settings(max_examples=1500, deadline=None)
@given(legs=legs_inputs, stamp=stamps)
def test_handle_never_raises_and_names_every_rejection(service, legs, stamp):
    CASES[check_handle(service, legs, stamp)] += 1


@pytest.mark.parametrize("kind", list(KINDS))
def test_every_kind_of_input(service, kind):
    @settings(max_examples=KIND_EXAMPLES, deadline=None)
    @given(legs=KINDS[kind], stamp=stamps)
    def each(legs, stamp):
        assert check_handle(service, legs, stamp) == kind
    each()


def check_handle(service, legs, stamp) -> str:
    """What must hold for every input handed to the service; returns the kind of outcome."""
    st_ = service.stats
    before = (st_.handled, st_.published, st_.rejected)
    warm_before, last_before = _copy(service.warm_x), _copy(service.estimator.last_x)

    out = service.handle(legs, stamp)            # must not raise

    assert st_.handled == before[0] + 1
    assert st_.published + st_.rejected == st_.handled
    assert (out.pose is None) != (out.reason is None)
    want = expected_rejection(legs, service.metres_per_unit)
    if out.pose is None:
        assert isinstance(out.reason, str) and out.reason.strip() and "\n" not in out.reason
        assert st_.rejected == before[2] + 1
        # state kept: a rejected input does not move the warm start
        np.testing.assert_array_equal(service.warm_x, warm_before)
        np.testing.assert_array_equal(service.estimator.last_x, last_before)
        if want is not None:
            assert out.reason.startswith(want), (legs, out.reason)
            assert out.estimate is None
            return want if isinstance(want, str) else want[0] + "/" + want[1]
        # the estimator ran and did not converge: its status names the reason
        assert out.estimate is not None and not out.estimate.converged
        assert out.reason.split(":", 1)[0] in STATUSES, out.reason
        return f"not converged ({out.estimate.status})"
    # a pose: only for a converged input, finite, unit quaternion, stamped with the input's stamp
    assert want is None, (legs, want)
    assert out.estimate is not None and out.estimate.converged
    # converged: the largest leg residual within LEG_RTOL of the geometry's scale (or of the legs, if longer)
    legs_unit = np.asarray(legs, dtype=float).reshape(-1) / service.metres_per_unit
    assert out.estimate.max_residual <= LEG_RTOL * max(service.model.scale, float(np.max(legs_unit)))
    assert out.pose.stamp_ns == stamp and out.pose.frame_id == service.frame_id
    assert all(math.isfinite(v) for v in out.pose.position + out.pose.orientation)
    assert abs(math.fsum(v * v for v in out.pose.orientation) - 1.0) < 1e-9
    assert st_.published == before[1] + 1
    np.testing.assert_array_equal(service.warm_x, out.estimate.x)
    # the pose reproduces the legs it answers
    model = service.model
    legs_back = model.inverse_kinematics(out.estimate.x) * service.metres_per_unit
    np.testing.assert_allclose(legs_back, np.asarray(legs, dtype=float).reshape(-1), rtol=1e-12, atol=1e-9)
    return "solved"


def test_after_the_fuzzing_the_service_reports_and_tracks(service):
    """Runs after the property test (file order): the counters add up on /diagnostics and the
    service still tracks from its warm state."""
    values = service.diagnostics().as_dict()
    st_ = service.stats
    assert int(values["inputs received"]) == st_.handled + st_.dropped
    assert int(values["inputs solved"]) + int(values["inputs rejected"]) == st_.handled
    reasons = sum(int(v) for k, v in values.items() if k.startswith("rejected: "))
    assert reasons == st_.rejected
    # track on from wherever the fuzzing left the warm state
    x = service.warm_x
    legs = service.model.inverse_kinematics(x) * service.metres_per_unit * (1.0 + 1e-5)
    out = service.handle(legs, 1)
    assert out.pose is not None, out.reason
    assert out.estimate.start == "warm"


def test_report_cases(capsys):
    with capsys.disabled():
        print(f"\nservice fuzz cases: {sum(CASES.values())} ({dict(sorted(CASES.items()))})")
    # what the draws must satisfy: each was one of the kinds the checks know (check_handle returns no other)
    known = set(KINDS) | {"leg lengths too large", "leg lengths look like/leg lengths outside the configured limits"}
    assert all(k in known or k.startswith("not converged (") for k in CASES), CASES
