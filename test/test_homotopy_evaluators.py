"""The families' own evaluators of the compiled tracker (glpma_ros/modes/path_tracker.py: the 3-RPR and the 6-6
written out from their interpolated parameters) against the dense quadrics they replace, on random complex
members: the same residual, Jacobian and dF/dtau at random points, and the same endpoints when every start
solution is tracked to a random complex target."""
import numpy as np
import pytest

from glpma_ros.modes import monodromy
from glpma_ros.modes import path_tracker as pt
from glpma_ros.modes.homotopy_families import _crandn

FAMILIES = ("planar_3rpr", "hexapod_66")
#: the two evaluators sum the same products of order-one numbers in another order: they agree to a few units of
#: round-off times the number of terms (tens); 1e-12 of the largest entry leaves room for cancellation
SAME_EVALUATION = 1e-12
#: endpoints polished to round-off by Newton's method, of random complex members (reciprocal condition numbers
#: above about 1e-6): within round-off / rcond of each other, so 1e-8 of 1 + |z|
SAME_ENDPOINT = 1e-8
#: random complex members per family
MEMBERS = 3


@pytest.mark.parametrize("name", FAMILIES)
def test_the_family_evaluator_equals_the_dense_quadrics(name):
    family = monodromy.load_start_system(name).family
    n = family.n_unknowns
    rng = np.random.default_rng(34)
    for _ in range(MEMBERS):
        p0, p1 = family.random_params(rng), family.random_params(rng)
        structured = family.parameter_path(p0, p1)
        dense = pt.dense_path(family.coefficient_path(p0, p1))
        assert structured.kind != pt.DENSE and dense.kind == pt.DENSE
        for _ in range(4):
            z, tau, dtau = _crandn(rng, n), _crandn(rng, ()), _crandn(rng, ())
            for a, b in zip(pt.evaluate(dense, z, tau, dtau), pt.evaluate(structured, z, tau, dtau)):
                assert np.max(np.abs(a - b)) <= SAME_EVALUATION * np.max(np.abs(a))


@pytest.mark.parametrize("name", FAMILIES)
def test_the_family_evaluator_tracks_to_the_dense_quadrics_endpoints(name):
    """Every start solution to a random complex target along both: every path regular, the same distinct
    endpoints (as sets: round-off may pair a path's steps differently, never its endpoint)."""
    start = monodromy.load_start_system(name)
    family = start.family
    rng = np.random.default_rng(3434)
    for _ in range(MEMBERS):
        target = family.random_params(rng)
        gammas = np.full(len(start.solutions), pt.random_gammas(rng, 1)[0])
        ends = []
        for path in (pt.dense_path(family.coefficient_path(start.params, target)),
                     family.parameter_path(start.params, target)):
            z, _, outcome, _, _ = pt.track(path, start.solutions, gammas)
            assert np.all(outcome == pt.REGULAR), outcome
            assert len(pt.distinct(z)) == family.root_count
            ends.append(z)
        dense, structured = ends
        size = 1.0 + np.max(np.abs(dense), axis=1)
        gap = np.max(np.abs(structured[:, None, :] - dense[None, :, :]), axis=2) / size[None, :]
        assert np.all(gap.min(axis=1) <= SAME_ENDPOINT), gap.min(axis=1)
        assert sorted(gap.argmin(axis=1)) == list(range(family.root_count))
