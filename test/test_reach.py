"""Legs no pose can reach, told from the legs alone (the loop bounds of a pair of legs), and the status
classification as a pure function."""
import math

import numpy as np
import pytest

from glpma_ros.estimation.estimator import (
    NEAR_SINGULAR,
    STATIONARY,
    STATUS_BUDGET,
    STATUS_MAX_EVALS,
    STATUS_NEAR_SINGULAR,
    STATUS_NO_SOLUTION,
    classify,
)
from glpma_ros.models.reach import REACH_RTOL, PairBounds
from glpma_ros.models.rotations import rotation_from_vector
from glpma_ros.solvers.local import LocalResult


def _poses(model, rng, n):
    if model.kind == "planar_3rpr":
        return [np.array([*rng.uniform(-300, 300, 2), rng.uniform(-math.pi, math.pi)]) for _ in range(n)]
    return [model.pose_variables((rotation_from_vector(rng.normal(0, 1.0, 3)), rng.uniform(-1500, 1500, 3)))
            for _ in range(n)]


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_legs_of_any_pose_pass_the_bounds(kind, request):
    """The bounds are necessary: the legs of a real pose (anywhere, any orientation, stretched or folded
    legs included) never break them."""
    model = request.getfixturevalue(kind)
    bounds = PairBounds(model)
    rng = np.random.default_rng(7)
    for x in _poses(model, rng, 2000):
        legs = model.inverse_kinematics(x)
        assert bounds.check(legs) is None, (x, legs)


def test_the_bounds_name_the_pair_and_the_bound(rpr, hexapod):
    told = PairBounds(rpr).check([60.0, 60.0, 60.0])
    # legs 2 and 3: base joints (200, 0), (0, 200), platform joints (50, 0), (40, 40): the legs' 120 fall short
    # of the difference of the two distances (relative tolerance: round-off of a few operations)
    excess = math.hypot(200, 200) - math.hypot(10, 40) - 120
    assert (told.i, told.j) == (1, 2) and told.excess == pytest.approx(excess, rel=1e-12)
    assert "legs 2 and 3" in told.why
    told = PairBounds(rpr).check([10.0, 10.0, 400.0])
    assert "differ by 390" in told.why
    assert PairBounds(hexapod).check([100.0] * 6) is not None
    assert PairBounds(hexapod).check([1250.0] * 6) is None
    # exactly on a bound (a fully stretched pair): a singular but real assembly, not told
    a = 200.0                   # legs 1 and 2 of the 3-RPR: base joints 200 apart, platform joints 50 apart
    assert PairBounds(rpr).check([a - 50.0 - 1.0 + REACH_RTOL, 1.0, 300.0]) is None


def _point(leg_fitness=1.0, conditioning=0.5, stationarity=1.0, progress=1.0):
    return LocalResult(np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), False, 1.0, leg_fitness, 1.0,
                       conditioning, stationarity, progress, 0.0, 0.0, 1, 1)


def test_classify_is_decided_by_the_work_done(rpr):
    far = 3 * 1e4         # a leg fitness far above round-off (RMS 100 mm on the 3-RPR)
    stationary = _point(far, stationarity=STATIONARY / 2)
    kw = dict(probe_complete=True, probe_converged=False, out_of_time=True)
    assert classify(stationary, rpr, **kw)[0] == STATUS_NO_SOLUTION
    assert classify(stationary, rpr, **{**kw, "probe_complete": False})[0] == STATUS_BUDGET   # the probe was cut
    assert classify(stationary, rpr, **{**kw, "probe_converged": True})[0] == STATUS_BUDGET
    assert classify(stationary, rpr, **{**kw, "probe_converged": True, "out_of_time": False})[0] == STATUS_MAX_EVALS
    singular = _point(1e-2, conditioning=NEAR_SINGULAR / 2)
    assert classify(singular, rpr, **kw)[0] == STATUS_NEAR_SINGULAR
    moving = _point(far)                           # neither stationary nor stalled: the search was short
    assert classify(moving, rpr, **kw)[0] == STATUS_BUDGET
    assert classify(moving, rpr, **kw) == classify(moving, rpr, **kw)      # no state, no clock
