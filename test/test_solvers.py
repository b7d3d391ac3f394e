"""Solvers: cold-start success with the default configuration, properties of the
pure algorithms (PCX distribution, elitism, monotone best, exact evaluation
counts, reproducibility) and the deadline."""
import numpy as np
import pytest

from conftest import check_deadline
from glpma_ros import solvers
from glpma_ros.solvers import g3pcx, glpma, rcga
from glpma_ros.solvers.common import Termination
from glpma_ros.solvers.driver import Problem

SOLVER_NAMES = ["g3pcx", "rcga", "glpma"]
#: solves per budget in the deadline test (the distribution is the benchmark's)
DEADLINE_RUNS = 10


@pytest.mark.parametrize("name", SOLVER_NAMES)
def test_rpr_cold_start_default_config_always_converges(rpr, name):
    """001 protocol: U[-50, 50]^3, 10,000 evaluations, seeds 0..99, refinement on."""
    legs = rpr.example_leg_lengths
    fits = [solvers.solve(name, rpr, legs, rng=seed).fun for seed in range(100)]
    assert sum(f < 1e-20 for f in fits) == 100, max(fits)


@pytest.mark.parametrize("name", SOLVER_NAMES)
def test_hexapod_cold_start_default_config_always_converges(hexapod, name):
    """001 protocol: U[-1000, 1000]^9, 500,000 evaluations, 20 seeds, refinement on."""
    legs = hexapod.example_leg_lengths
    results = [solvers.solve(name, hexapod, legs, rng=seed) for seed in range(20)]
    assert all(r.fun < 1e-20 and r.status == "converged" for r in results), [r.fun for r in results]
    assert all(r.nfev <= 500_000 for r in results)


def test_pcx_children_centred_on_index_parent_with_stated_spreads():
    rng = np.random.default_rng(0)
    parents = np.array([[1.0, 0.0, 0.0], [-1.0, 1.0, 0.0], [-1.0, -1.0, 0.0]])
    g = parents.mean(axis=0)
    d = parents[0] - g
    dhat = d / np.linalg.norm(d)
    # mean perpendicular distance of the other parents to the line through g along d
    perp = [np.linalg.norm((p - g) - ((p - g) @ dhat) * dhat) for p in parents[1:]]
    D_bar = np.mean(perp)
    kids = g3pcx.pcx_children(parents, 40000, 0.1, 0.1, rng, parents)      # independent children
    offsets = kids - parents[0]
    along = offsets @ dhat
    across = offsets - np.outer(along, dhat)
    n = len(kids)
    assert abs(offsets.mean(axis=0)).max() < 4 * 0.1 * max(np.linalg.norm(d), D_bar) / np.sqrt(n)
    assert np.std(along) == pytest.approx(0.1 * np.linalg.norm(d), rel=0.03)
    # two perpendicular directions, each with standard deviation sigma_eta * D_bar
    assert np.sqrt((across ** 2).sum(axis=1).mean() / 2) == pytest.approx(0.1 * D_bar, rel=0.03)


def test_pcx_degenerate_parents_do_not_divide_by_zero():
    rng = np.random.default_rng(0)
    parents = np.ones((3, 4))
    pop = np.vstack([parents, parents + 1.0])
    kids = g3pcx.pcx_children(parents, 2, 0.1, 0.1, rng, pop)
    assert np.all(np.isfinite(kids)) and not np.allclose(kids, 1.0)


def _pure(name, model, seed, max_evals):
    return solvers.solve(name, model, model.example_leg_lengths, rng=seed, polish=False, max_evals=max_evals)


@pytest.mark.parametrize("name", SOLVER_NAMES)
def test_pure_solvers_best_fitness_is_monotone_and_elitist(rpr, name):
    r = _pure(name, rpr, 3, 5000)
    best = [f for _, f in r.history]
    assert all(b2 <= b1 for b1, b2 in zip(best, best[1:]))
    assert best[-1] == r.fun
    assert r.fun == pytest.approx(rpr.fitness(r.x, rpr.example_leg_lengths)[0], rel=1e-9)


@pytest.mark.parametrize("name", SOLVER_NAMES)
def test_seeds_reproduce(rpr, name):
    a, b = _pure(name, rpr, 7, 2000), _pure(name, rpr, 7, 2000)
    c = _pure(name, rpr, 8, 2000)
    assert np.array_equal(a.x, b.x) and a.nfev == b.nfev
    assert not np.array_equal(a.x, c.x)


def test_g3pcx_counts_evaluations_exactly(rpr):
    """Initial population plus lambda children per generation, never past the cap."""
    r = solvers.solve("g3pcx", rpr, rpr.example_leg_lengths, rng=1, polish=False, max_evals=3001)
    assert r.status in ("max_evals", "converged")
    assert r.nfev == 100 + g3pcx.LAMBDA * r.nit
    assert r.nfev <= 3001


@pytest.mark.parametrize("name", SOLVER_NAMES)
@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_evaluations_match_the_kernels_own_counter(rpr, hexapod, name, kind):
    """Pure solvers: ``nfev`` equals the residual evaluations the compiled kernel counted."""
    model = rpr if kind == "rpr" else hexapod
    model.evaluation_counter[0] = 0
    r = solvers.solve(name, model, model.example_leg_lengths, rng=2, polish=False, max_evals=4000)
    assert r.nfev == model.evaluation_counter[0] and r.nfev <= 4000


def test_rcga_keeps_the_elite(rpr):
    rng = np.random.default_rng(0)
    term = Termination(max_evals=10_000)
    problem = Problem(rpr, rpr.example_leg_lengths)
    pop = rng.uniform(-50, 50, (50, 3))
    state = rcga.RCGAPopulation(problem, pop, problem.evaluate(pop, term), rng, width=100.0, max_evals=10_000)
    for _ in range(30):
        before = state.best()[1]
        state.step(1, term)
        assert state.best()[1] <= before


def test_glpma_local_population_persists_between_local_searches(rpr):
    rng = np.random.default_rng(0)
    term = Termination(max_evals=10_000)
    problem = Problem(rpr, rpr.example_leg_lengths)
    mp = rng.uniform(-50, 50, (20, 3))
    lp = rng.uniform(-50, 50, (20, 3))
    master = rcga.RCGAPopulation(problem, mp, problem.evaluate(mp, term), rng, width=100.0, max_evals=10_000)
    local = g3pcx.G3PCXPopulation(problem, lp, problem.evaluate(lp, term), rng)
    state = glpma.GLPMAState(master, local, ls_interval=2, ls_intensity=3)
    local_pop = local.pop
    state.step(2, term)
    assert local.pop is local_pop            # same population object, evolved in place
    meme_best = master.best()[1]
    assert meme_best <= local.best()[1] or np.isclose(meme_best, local.best()[1])


@pytest.mark.timing
@pytest.mark.parametrize("budget_ms", [1.0, 2.0, 5.0])
def test_deadline_is_honoured(hexapod, budget_ms):
    """Pure cold G3-PCX on the hexapod cannot converge in a few ms; it must stop
    at the deadline, with ``budget_exhausted``, within the bound of ``check_deadline`` (which
    holds on a busy machine); how close to the budget it stops is the benchmark's."""
    legs = hexapod.example_leg_lengths
    # compiled (or loaded from the cache) outside the timed solves: the deadline path too
    solvers.solve("g3pcx", hexapod, legs, rng=0, polish=False, max_evals=1000)
    solvers.solve("g3pcx", hexapod, legs, rng=0, polish=False, budget_s=budget_ms / 1e3)

    def solve(seed):
        r = solvers.solve("g3pcx", hexapod, legs, rng=seed, polish=False, budget_s=budget_ms / 1e3)
        assert r.status == "budget_exhausted", (seed, r.status)

    check_deadline(solve, budget_ms, DEADLINE_RUNS)
