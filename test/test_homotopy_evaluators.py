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


#: the lockstep kernel and the path-by-path one take the same steps up to round-off, which may move a step
#: decision near its threshold: a path's step count may differ by a few (the A/B on 840 paths: 19 differed, by 1 or 2)
STEP_SLACK = 4


def test_the_6_6_lockstep_follows_each_path_as_alone():
    """The 6-6's lockstep kernel (``LANES`` paths together) against the path-by-path one (``track_paths_alone``) on the
    same parameter path: every path the same outcome and endpoint, about the same steps; a path count that is not a
    multiple of the lanes (and fewer paths than lanes) leaves a path's endpoint as it was."""
    start = monodromy.load_start_system("hexapod_66")
    family, n = start.family, start.family.n_unknowns
    rng = np.random.default_rng(343434)
    path = family.parameter_path(start.params, family.random_params(rng))
    gammas = np.full(len(start.solutions), pt.random_gammas(rng, 1)[0])
    lockstep = pt.track(path, start.solutions, gammas, threads=1)
    assert np.count_nonzero(lockstep[2] == pt.REGULAR) >= len(start.solutions) // 2     # real work
    count = len(start.solutions)
    alone = (np.empty((count, n), complex), np.empty((count, n, n), complex), np.empty(count, np.int64),
             np.empty(count, np.int64), np.empty(count))
    pt.track_paths_alone(path.kind, path.K, path.P, np.ascontiguousarray(start.solutions), gammas, pt.SETTINGS, *alone)
    assert np.array_equal(alone[2], lockstep[2])
    assert np.all(np.abs(alone[3] - lockstep[3]) <= STEP_SLACK)
    regular = alone[2] == pt.REGULAR
    size = 1.0 + np.max(np.abs(alone[0][regular]), axis=1)
    assert np.all(np.max(np.abs(alone[0][regular] - lockstep[0][regular]), axis=1) <= SAME_ENDPOINT * size)
    for few in (slice(0, 3), slice(5, 16)):
        part = pt.track(path, start.solutions[few], gammas[few], threads=1)
        assert np.array_equal(part[2], lockstep[2][few])
        size = 1.0 + np.max(np.abs(part[0]), axis=1)
        assert np.all(np.max(np.abs(part[0] - lockstep[0][few]), axis=1) <= SAME_ENDPOINT * size)
