"""No work after the deadline, counted on a fake clock: every solver and the Estimator.

``time.perf_counter`` and ``time.thread_time`` are replaced by one clock that moves only when it is
read (by READ_TICK_S) and when compiled work runs (by WORK_TICK_S per call, per generation for a chunk of
generations); every compiled call the
solvers and the Estimator make (population evaluations and generations, the Levenberg-Marquardt
kernels, the round-off search's evaluations, the leave-one-out solves of redundant legs) records the
clock when it starts.  A call that starts after the deadline is work after the deadline: none may; and
the call returns within one compiled call of its deadline.  Python's garbage collector is work too: with
its threshold lowered so that it would run at almost every allocation, each collection moves the clock by
COLLECTION_TICK_S and none may start after the deadline.  No wall-clock figure is asserted (the real
overruns are measured by ``glpma-fk bench``, deadline section)."""
import gc
import math
import time

import numpy as np
import pytest

from conftest import CONFIG
from glpma_ros import solvers
from glpma_ros.config import load_document, load_manipulator, model_from_dict
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.runtime import clock as kernel_clock
from glpma_ros.runtime import precompile
from glpma_ros.runtime.collector import CollectorHold
from glpma_ros.solvers import de, driver, g3pcx, gasa, glpma, lm, local, rcga, refine
from glpma_ros.solvers.common import Termination, initial_population

#: what reading the clock costs on the fake clock (a few hundred nanoseconds on a real one)
READ_TICK_S = 2e-7
#: what one compiled call costs on the fake clock (tens of microseconds: a chunk of generations, a
#: Levenberg-Marquardt solve)
WORK_TICK_S = 20e-6
#: fake budgets: from "nothing fits" to "the deciding work fits" (on the fake clock it takes
#: 2 settles + 8 probe calls, about 0.2 ms)
BUDGETS_S = (0.0, 1e-4, 5e-4, 2e-3)
#: legs with no real assembly that the loop bounds of a pair of legs do not tell (so the search, the
#: settle and the probe all run), and feasible legs
RPR_CASES = ([400.0, 400.0, 400.0], [100.0, 120.0, 150.0])
HEX_CASES = ([900.0, 1600.0] * 3, [1000.0] * 5 + [1500.0])
#: what may follow the last compiled call on the fake clock: reading the clock and the Python around it
RETURN_READS = 1000
#: a gross error on one leg of the 7-leg hexapod (mm): a thousand times its leg noise (0.01 mm)
FAULT_MM = 10.0
#: a budget on the fake clock in which the whole isolation of a faulty leg fits (7 leave-one-out solves
#: from the previous pose, or 7 x 8 calls of the fixed starts without one, at WORK_TICK_S each)
ISOLATION_FITS_S = 0.05
#: what one collection of the young objects costs on the fake clock (0.1-0.7 ms measured in the bench's
#: process, Numba and SciPy loaded)
COLLECTION_TICK_S = 3e-4
#: the collector's thresholds while collections are simulated: one collection of the youngest generation
#: every second allocation of a container (the older generations never: a full collection takes
#: tens of milliseconds of the test's real time, and the young one is what runs inside a solve)
COLLECT_OFTEN = (1, 10**9, 10**9)
#: budgets on the fake clock that hold a few collections and a few compiled calls
COLLECTION_BUDGETS_S = (1e-3, 3e-3)
#: what building a solver's result (the Python after its last compiled call) costs on the fake clock: more
#: than the return allowance of _returned_in_time, so a solve that leaves no room for it returns late
RESULT_TICK_S = 5e-4
#: GLPMA's settings on the 6-6 hexapod (the paper's): a master generation is 200 children, a local search
#: 85 G3-PCX generations every 5 master generations -- a chunk of one master generation is 0.15-0.3 ms of work
HEX_GLPMA = {"population": 200, "local_population": 200, "ls_interval": 5, "ls_intensity": 85}
#: the solver variables' initial range on the hexapod (its default, mm)
HEX_RANGE = (-1000.0, 1000.0)
#: time each chunk of the resumed run is given (s): less than a hexapod master generation (about 0.15 ms),
#: so most chunks stop inside one, wherever the clock lands
SHORT_CHUNK_S = 1e-4
#: master generations both runs of the resume test make: three local searches (one every 5)
RESUMED_GENERATIONS = 15
#: the same children from the same random stream, evaluated in the same order: the same floats (up to
#: the last bits, which the tests never compare)
SAME_RTOL = 1e-12
#: time each chunk of the resumed G3-PCX run is given (s): a few generations (a few microseconds each) after the
#: call's entry (10-50 µs), so that the clock cuts most chunks
G3PCX_CHUNK_S = 5e-5
#: a DE chunk's work deadline in the test that cuts one inside a generation: a few generations of the hexapod's
#: ~90 trials (a trial is under a microsecond)
DE_CHUNK_S = 2e-4
#: G3-PCX generations both runs of its resume test make
G3PCX_GENERATIONS = 400


class FakeClock:
    def __init__(self):
        self.now = 1000.0
        self.starts = []            # clock at the start of each compiled call, while recording
        self.collections = []       # clock at the start of each garbage collection, while recording one
        self.collection_s = 0.0     # what a collection costs on this clock (0: collections are not watched)
        self.recording = False

    def on_collection(self, phase, info):
        """A ``gc.callbacks`` entry: a collection while recording is work that moves the clock."""
        if phase == "start" and self.recording and self.collection_s:
            self.collections.append(self.now)
            self.now += self.collection_s

    def read(self):
        self.now += READ_TICK_S
        return self.now

    def work(self, fn, per_generation=False):
        def call(*args, **kwargs):
            if self.recording:
                self.starts.append(self.now)
            self.now += WORK_TICK_S * (args[1] if per_generation else 1)
            return fn(*args, **kwargs)
        return call

    def run(self, fn, *args, **kwargs):
        """``fn(*args, **kwargs)`` with the starts of its compiled calls recorded (afresh); returns its result
        and the clock when it was called."""
        self.starts.clear()
        self.collections.clear()
        if self.collection_s:
            gc.collect(0)           # the young generation empty: no collection before ``fn`` is entered
        self.recording = True
        start = self.now
        try:
            result = fn(*args, **kwargs)
        finally:
            self.recording = False      # before building the returned pair: the caller's allocation
        return result, start


@pytest.fixture
def clock(monkeypatch):
    c = FakeClock()
    # the costs a solve measured on the real clock (kept for the next solve of that solver and model, and the
    # round-off search's round) are not this clock's: a test on it starts from none, whatever ran before it
    monkeypatch.setattr(driver, "_LAST_COSTS", {})
    monkeypatch.setattr(refine, "_ROUND_S", {})
    monkeypatch.setattr("time.perf_counter", c.read)
    monkeypatch.setattr("time.thread_time", c.read)
    for module, name in ((local, "lm_kernel"), (local, "multistart_kernel"), (lm, "lm_kernel"), (lm, "warm_kernel"),
                         (driver, "population_fitness")):
        monkeypatch.setattr(module, name, c.work(getattr(module, name)))
    # step(self, n_generations, term)
    step = driver.EvolutionaryState.step
    monkeypatch.setattr(driver.EvolutionaryState, "step", c.work(step, per_generation=True))
    # GA-SA's chunk is compiled calls of a few Markov chains with the clock read between them: each call counts
    monkeypatch.setattr(gasa.GASAPopulation, "step", step, raising=False)
    monkeypatch.setattr(gasa, "gasa_generations", c.work(gasa.gasa_generations))
    # the fake clock charges a chunk its generations before it runs; the kernels' own clock reads the real one,
    # which the fake clock does not move: here they run the generations they are asked for (their stop inside
    # a generation is counted by the tests below, on the real clock)
    for module in (rcga, g3pcx, de):
        monkeypatch.setattr(module, "kernel_end", lambda deadline: math.inf)
    # ... so no kernel stops itself here: a chunk is sized by the time left, as for every other solver
    monkeypatch.setattr(g3pcx.G3PCXPopulation, "stops_itself", False)
    return c


def _watch_model(monkeypatch, clock, model):
    """The round-off search evaluates through the model itself."""
    monkeypatch.setattr(model, "fitness", clock.work(model.fitness))


@pytest.fixture
def collector(clock):
    """Python's garbage collector running at almost every allocation, each collection costing
    COLLECTION_TICK_S on the fake clock."""
    thresholds, enabled = gc.get_threshold(), gc.isenabled()
    clock.collection_s = COLLECTION_TICK_S
    gc.callbacks.append(clock.on_collection)
    gc.enable()
    gc.set_threshold(*COLLECT_OFTEN)
    try:
        yield clock
    finally:
        gc.set_threshold(*thresholds)
        gc.callbacks.remove(clock.on_collection)
        if not enabled:
            gc.disable()


def _late(clock, deadline):
    return [round((t - deadline) * 1e6, 3) for t in clock.starts + clock.collections if t >= deadline]


def _returned_in_time(end, deadline):
    """Within one compiled call (and the clock reads around it) of the deadline."""
    return end <= deadline + WORK_TICK_S + RETURN_READS * READ_TICK_S


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_no_solver_works_after_its_deadline(kind, clock, monkeypatch, request):
    model = request.getfixturevalue(kind)
    _watch_model(monkeypatch, clock, model)
    for legs in RPR_CASES if kind == "rpr" else HEX_CASES:
        for name in solvers.SOLVERS:
            for budget in BUDGETS_S[1:]:          # the first evaluation runs whatever the budget
                _, start = clock.run(solvers.solve, name, model, np.array(legs), rng=0, budget_s=budget,
                                     max_evals=10**9)
                assert clock.starts, (name, budget)
                assert not _late(clock, start + budget), (name, legs, budget, "µs late", _late(clock, start + budget))
                assert _returned_in_time(clock.now, start + budget), (name, legs, budget, clock.now - start - budget)


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_no_solver_works_after_its_deadline_from_a_warm_start(kind, clock, monkeypatch, request):
    """A warm population (the Estimator's warm and widened stages): the refinement of the previous estimate
    comes first, then the chunks; none starts after the deadline, and each solver returns within one call."""
    model = request.getfixturevalue(kind)
    center = request.getfixturevalue("rpr_solutions" if kind == "rpr" else "hex_published")[1]
    _watch_model(monkeypatch, clock, model)
    for legs in RPR_CASES if kind == "rpr" else HEX_CASES:
        for name in solvers.SOLVERS:
            for budget in BUDGETS_S[1:]:
                _, start = clock.run(solvers.solve, name, model, np.array(legs), rng=0, budget_s=budget,
                                     max_evals=10**9, center=center, spread=model.spread_vector(0.01 * model.scale))
                deadline = start + budget
                assert clock.starts and not _late(clock, deadline), (name, legs, budget, _late(clock, deadline))
                assert _returned_in_time(clock.now, deadline), (name, legs, budget, clock.now - deadline)


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
@pytest.mark.parametrize("warm", [False, True])
def test_the_estimator_does_no_work_after_its_deadline(kind, warm, clock, monkeypatch, request):
    """Cold and warm (from a pose far from the legs' assembly, so that every stage runs), on legs with
    and without an assembly: every compiled call starts before the deadline, and the estimate is
    returned within one call's time of it; when the deciding work did not fit, ``budget_exhausted``."""
    model = request.getfixturevalue(kind)
    start_x = request.getfixturevalue("rpr_solutions" if kind == "rpr" else "hex_published")[1] if warm else None
    statuses = set()
    above = {}                # legs -> statuses at budgets above the smallest deciding budget
    for legs in RPR_CASES if kind == "rpr" else HEX_CASES:
        for budget in BUDGETS_S:
            est = Estimator(model, time_budget_s=budget, initial_pose=start_x, max_evals=10**9)
            _watch_model(monkeypatch, clock, model)
            e, start = clock.run(est.estimate, legs)
            end = clock.now
            deadline = start + budget
            assert not _late(clock, deadline), (legs, budget, e.status, "µs late", _late(clock, deadline))
            assert _returned_in_time(end, deadline), (legs, budget, e.status, end - deadline)
            if budget == 0.0:
                assert e.status == "budget_exhausted" and not clock.starts
            statuses.add(e.status)
            if budget >= est.smallest_deciding_budget_s:
                # above the smallest deciding budget the deciding work fits: the status is the work's
                above.setdefault(tuple(legs), set()).add(e.status)
    assert "budget_exhausted" in statuses and statuses & {"converged", "no_solution"}, statuses
    assert above and all(len(s) == 1 and s <= {"converged", "no_solution"} for s in above.values()), above


def _eight_legs():
    """The 7-leg hexapod with an eighth leg: two redundant legs, so the faulty one is found without history
    (from the fixed starts)."""
    doc = load_document(CONFIG / "hexapod_7legs.yaml")
    doc["base"].append([-300.0, -350.0, -178.7])
    doc["platform"].append([150.0, 200.0, 236.4])
    doc.pop("example_leg_lengths")
    return model_from_dict(doc), np.array(doc["published_solutions"][0])


@pytest.mark.parametrize("warm", [False, True])
def test_the_isolation_of_a_faulty_leg_does_no_work_after_its_deadline(warm, clock, monkeypatch):
    """Redundant legs with one leg off by a thousand times its noise -- the 7-leg hexapod from its previous
    pose, the 8-leg one cold: the leave-one-out solves that find it start only before the deadline; an
    isolation cut there is ``budget_exhausted`` with no leg named, one that fits names the faulty leg."""
    if warm:
        model = load_manipulator(CONFIG / "hexapod_7legs.yaml")
        x = np.array(load_document(CONFIG / "hexapod_7legs.yaml")["published_solutions"][0])
    else:
        model, x = _eight_legs()
    legs = model.inverse_kinematics(x)
    legs[3] += FAULT_MM
    found = {}
    for budget in BUDGETS_S[1:] + (ISOLATION_FITS_S,):
        est = Estimator(model, time_budget_s=budget, initial_pose=x if warm else None, max_evals=10**9)
        _watch_model(monkeypatch, clock, model)
        e, start = clock.run(est.estimate, legs)
        deadline = start + budget
        assert not _late(clock, deadline), (budget, e.status, "µs late", _late(clock, deadline))
        assert _returned_in_time(clock.now, deadline), (budget, e.status, clock.now - deadline)
        found[budget] = (e.status, e.suspect_leg)
    assert found[ISOLATION_FITS_S] == ("inconsistent_legs", 3), found
    assert ("budget_exhausted", None) in found.values(), found


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_no_garbage_collection_runs_after_a_deadline(kind, collector, monkeypatch, request):
    """Every solver and the Estimator, cold, on legs with no real assembly (they search until the deadline),
    with the garbage collector running at almost every allocation: a collection is a pause the clock checks
    between compiled calls do not bound, so none may start after the deadline (nor delay a compiled call or
    the return past it)."""
    model = request.getfixturevalue(kind)
    legs = np.array((RPR_CASES if kind == "rpr" else HEX_CASES)[0])
    _watch_model(monkeypatch, collector, model)
    for budget in COLLECTION_BUDGETS_S:
        for name in solvers.SOLVERS:
            _, start = collector.run(solvers.solve, name, model, legs, rng=0, budget_s=budget, max_evals=10**9)
            deadline = start + budget
            assert not _late(collector, deadline), (name, budget, "µs late", _late(collector, deadline))
            assert _returned_in_time(collector.now, deadline), (name, budget, collector.now - deadline)
        est = Estimator(model, time_budget_s=budget, max_evals=10**9)
        e, start = collector.run(est.estimate, legs)
        deadline = start + budget
        assert not _late(collector, deadline), (budget, e.status, "µs late", _late(collector, deadline))
        assert _returned_in_time(collector.now, deadline), (budget, e.status, collector.now - deadline)
    assert gc.isenabled()       # the collector is back on after the solves


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_a_solver_leaves_room_for_building_its_result(kind, clock, monkeypatch, request):
    """The Python after a solver's last compiled call (its result built) costs RESULT_TICK_S on the fake clock:
    measured by one solve, it is left room for by the next ones of that solver, which return within one
    compiled call of their deadline."""
    model = request.getfixturevalue(kind)
    legs = np.array((RPR_CASES if kind == "rpr" else HEX_CASES)[0])
    _watch_model(monkeypatch, clock, model)
    monkeypatch.setattr(driver, "_LAST_COSTS", {})          # this test's fake costs stay in this test
    result = driver.SolveResult

    def slow_result(*args, **kwargs):
        clock.now += RESULT_TICK_S
        return result(*args, **kwargs)
    monkeypatch.setattr(driver, "SolveResult", slow_result)
    for name in solvers.SOLVERS:
        clock.run(solvers.solve, name, model, legs, rng=0, budget_s=COLLECTION_BUDGETS_S[-1], max_evals=10**9)
        for budget in COLLECTION_BUDGETS_S:
            _, start = clock.run(solvers.solve, name, model, legs, rng=1, budget_s=budget, max_evals=10**9)
            deadline = start + budget
            assert not _late(clock, deadline), (name, budget, "µs late", _late(clock, deadline))
            assert _returned_in_time(clock.now, deadline), (name, budget, clock.now - deadline)


def _glpma_hexapod(model, seed):
    """GLPMA's state with its hexapod settings on legs no pose reaches (so nothing converges), and its
    termination without a cap."""
    rng = np.random.default_rng(seed)
    term = Termination(max_evals=10**9)
    problem = driver.Problem(model, np.array(HEX_CASES[0]))
    n = model.n_vars
    mp = initial_population(rng, HEX_GLPMA["population"], n, HEX_RANGE, None, None)
    master = rcga.RCGAPopulation(problem, mp, problem.evaluate(mp, term), rng,
                                 width=rcga.mutation_width(HEX_RANGE, None, n), max_evals=10**9)
    lp = initial_population(rng, HEX_GLPMA["local_population"], n, HEX_RANGE, None, None)
    local_pop = g3pcx.G3PCXPopulation(problem, lp, problem.evaluate(lp, term), rng)
    return glpma.GLPMAState(master, local_pop, HEX_GLPMA["ls_interval"], HEX_GLPMA["ls_intensity"]), term


@pytest.mark.parametrize("into_local_search", [False, True])
def test_a_glpma_chunk_does_no_work_after_its_work_deadline(hexapod, into_local_search):
    """Counted evaluations: a chunk of GLPMA whose work deadline has passed makes none -- its kernels read
    the clock inside a master generation (between two children) and inside a local search (between two
    G3-PCX generations), not only between chunks, where a whole master generation and its share of the
    local search (0.15-0.3 ms on the hexapod) would run past the deadline."""
    state, term = _glpma_hexapod(hexapod, seed=0)
    if into_local_search:       # into a local search cut at its chunk's share: the next chunk resumes it first
        state.step(HEX_GLPMA["ls_interval"] - 1, term)
        state.step(1, term)
        assert 0 < state.local_left < HEX_GLPMA["ls_intensity"]
    before = term.nfev
    state.work_deadline = time.perf_counter()
    gens = state.step(1, term)
    assert (gens, term.nfev - before) == (0, 0) and state.out_of_time
    state.work_deadline = None  # no deadline: the same chunk runs
    assert state.step(1, term) >= 0 and term.nfev > before and not state.out_of_time


def test_glpma_stopped_inside_its_generations_resumes_them_exactly(hexapod):
    """Chunks cut short by the clock (inside master generations and local searches, wherever it lands) make
    the same generations as chunks without a deadline: the same populations and the same evaluations."""
    def run(chunk_s, generations):
        """Chunks of one master generation until ``generations`` are done and no generation or local search is
        under way; each chunk given ``chunk_s`` (None: no deadline).  The state, its termination and the chunks
        the clock cut."""
        state, term = _glpma_hexapod(hexapod, seed=1)
        cut = 0
        while state.master.generation < generations or state.local_left or state.master.progress[0]:
            state.work_deadline = None if chunk_s is None else time.perf_counter() + chunk_s
            state.step(1, term)
            cut += state.out_of_time
        return state, term, cut

    whole, whole_term, _ = run(None, RESUMED_GENERATIONS)
    # the same number of generations: a chunk that finishes a local search also runs the next master generation
    # unless the clock stops it there, so the run without a deadline may end one generation later than asked
    cut, cut_term, stops = run(SHORT_CHUNK_S, whole.master.generation)
    assert stops > 0            # the clock did cut chunks
    assert cut.master.generation == whole.master.generation and cut_term.nfev == whole_term.nfev
    for a, b in ((cut.master.pop, whole.master.pop), (cut.master.fit, whole.master.fit),
                 (cut.local.pop, whole.local.pop), (cut.local.fit, whole.local.fit)):
        np.testing.assert_allclose(a, b, rtol=SAME_RTOL)


def _g3pcx_hexapod(model, seed):
    """A G3-PCX population on hexapod legs no pose reaches (nothing converges), and a termination without a cap."""
    rng = np.random.default_rng(seed)
    term = Termination(max_evals=10**9)
    problem = driver.Problem(model, np.array(HEX_CASES[0]))
    pop = initial_population(rng, HEX_GLPMA["local_population"], model.n_vars, HEX_RANGE, None, None)
    return g3pcx.G3PCXPopulation(problem, pop, problem.evaluate(pop, term), rng), term


def test_a_g3pcx_chunk_does_no_work_after_its_work_deadline(hexapod):
    """Counted evaluations: a G3-PCX chunk whose work deadline has passed makes none (its kernel reads the clock
    before each generation) and says so; it reports how long the call took to reach its kernel, the fixed cost
    a chunk must leave room for.  Without a deadline the same chunk runs and the kernel never reads the clock."""
    state, term = _g3pcx_hexapod(hexapod, seed=0)
    before = term.nfev
    state.work_deadline = time.perf_counter()
    gens = state.step(driver.CHUNK_GENERATIONS, term)
    assert (gens, term.nfev - before) == (0, 0) and state.out_of_time and state.entry_s > 0.0
    state.work_deadline = None
    assert state.step(driver.CHUNK_GENERATIONS, term) == driver.CHUNK_GENERATIONS
    assert term.nfev - before == driver.CHUNK_GENERATIONS * g3pcx.LAMBDA and not state.out_of_time
    assert state.entry_s == 0.0


def test_g3pcx_stopped_by_the_clock_resumes_exactly(hexapod):
    """Chunks cut short by the clock make the same generations as chunks without a deadline: the clock is read
    before a generation draws anything, so the next chunk goes on with the same random stream."""
    def run(chunk_s):
        state, term = _g3pcx_hexapod(hexapod, seed=1)
        done = cut = 0
        while done < G3PCX_GENERATIONS:
            state.work_deadline = None if chunk_s is None else time.perf_counter() + chunk_s
            done += state.step(G3PCX_GENERATIONS - done, term)
            cut += state.out_of_time
        return state, term, cut

    whole, whole_term, _ = run(None)
    cut, cut_term, stops = run(G3PCX_CHUNK_S)
    assert stops > 0            # the clock did cut chunks
    assert cut_term.nfev == whole_term.nfev
    np.testing.assert_allclose(cut.pop, whole.pop, rtol=SAME_RTOL)
    np.testing.assert_allclose(cut.fit, whole.fit, rtol=SAME_RTOL)


def test_a_de_chunk_does_no_work_after_its_work_deadline(hexapod):
    """Counted evaluations: a DE chunk whose work deadline has passed evaluates no trial (its kernel reads the
    clock before each block of trials) and says so; without a deadline the same chunk runs whole generations of
    ``Np`` evaluations.  A chunk cut inside a generation evaluated whole blocks of trials only, and left a
    population whose fitness is its members' (each evaluated trial replaced its own target or not)."""
    rng = np.random.default_rng(0)
    term = Termination(max_evals=10**9)
    problem = driver.Problem(hexapod, np.array(HEX_CASES[0]))
    pop = initial_population(rng, de.default_population(hexapod), hexapod.n_vars, HEX_RANGE, None, None)
    state = de.DEPopulation(problem, pop, problem.evaluate(pop, term), rng)
    before = term.nfev
    state.work_deadline = time.perf_counter()
    assert state.step(driver.CHUNK_GENERATIONS, term) == 0 and term.nfev == before and state.out_of_time
    state.work_deadline = None
    assert state.step(3, term) == 3 and term.nfev - before == 3 * len(pop) and not state.out_of_time
    cut = 0
    while not cut:                  # short work deadlines until one falls inside a generation's evaluations
        before = term.nfev
        state.work_deadline = time.perf_counter() + DE_CHUNK_S
        gens = state.step(driver.CHUNK_GENERATIONS, term)
        cut = (term.nfev - before) - gens * len(pop)
    assert state.out_of_time and cut % de.CLOCK_STRIDE == 0 and 0 < cut < len(pop)
    np.testing.assert_allclose(state.fit, problem.evaluate(state.pop, term), rtol=SAME_RTOL)


def test_a_chunk_that_stops_itself_is_sized_by_the_budget(hexapod, monkeypatch):
    """Late in a budget the chunk of a kernel that stops itself at the deadline is a share of the budget (within
    the time left), not of the time left; and none starts when the call's measured entry and a generation do not
    fit before the deadline."""
    now = 1000.0
    monkeypatch.setattr("time.perf_counter", lambda: now)
    budget = 1e-3
    costs = driver.Costs(Termination(max_evals=10**9, budget_s=budget, start=now - 0.8 * budget), "test", hexapod)
    costs.per_eval, costs.tail_s, costs.entry_s, costs.on_chunks = 4e-7, 0.0, 0.0, True
    state, _ = _g3pcx_hexapod(hexapod, seed=2)
    by_budget = costs.generations(state)
    monkeypatch.setattr(g3pcx.G3PCXPopulation, "stops_itself", False)
    by_time_left = costs.generations(state)
    # 0.2 ms left, a generation 2 evaluations of 0.4 µs: a tenth of the budget (0.1 ms) holds 125 generations, a
    # tenth of the time left (0.02 ms) 25; a chunk is a power of two, doubled while twice it fits: 64 and 16
    assert (by_budget, by_time_left) == (64, 16)
    costs.entry_s = 0.2 * budget
    assert costs.generations(state) == 0


def test_the_kernels_clock_is_the_one_python_reads():
    """The kernels' end is computed by ``kernel_end`` from ``time.monotonic()``: the compiled clock must read
    the same clock (ordered between two reads of it), and a deadline passes on both at once."""
    for _ in range(3):
        before = time.monotonic()
        compiled = kernel_clock.monotonic_s()
        assert before <= compiled <= time.monotonic()
    assert kernel_clock.kernel_end(None) == math.inf
    assert kernel_clock.kernel_end(time.perf_counter()) <= time.monotonic()


def test_the_collector_hold_nests_and_restores():
    """Nested holds (the Estimator around its solvers) keep the collector off until the outermost ends, which
    restores it as it found it: on, or off when the caller had turned it off."""
    enabled = gc.isenabled()
    hold = CollectorHold()
    try:
        for before in (True, False):
            if before:
                gc.enable()
            else:
                gc.disable()
            hold.acquire()
            assert not gc.isenabled()
            hold.acquire()
            assert not gc.isenabled()
            hold.release()
            assert not gc.isenabled()
            hold.release()
            assert gc.isenabled() == before
    finally:
        if enabled:
            gc.enable()
        else:
            gc.disable()


def test_a_round_of_the_round_off_search_starts_only_when_its_measured_time_fits(hexapod, monkeypatch):
    """Counted evaluations: a round measured at 1 s does not start before a deadline 0.5 s away (the candidates'
    evaluation alone is a fraction of a round's time, NumPy and Python around it); without a deadline every
    round runs (a target of 0 is never met)."""
    x = precompile.warm_up_pose(hexapod)
    legs = hexapod.inverse_kinematics(x)
    monkeypatch.setattr(refine, "_ROUND_S", {hexapod.kind: 1.0})
    rng = np.random.default_rng(0)
    _, _, nfev = refine.round_off_search(hexapod, x, legs, 1.0, rng, target=0.0, deadline=time.perf_counter() + 0.5)
    assert nfev == 0
    _, _, nfev = refine.round_off_search(hexapod, x, legs, 1.0, rng, target=0.0)
    assert nfev == refine.GRID_ROUNDS * refine.GRID_CANDIDATES
