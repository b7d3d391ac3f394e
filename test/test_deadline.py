"""No work after the deadline, counted on a fake clock: every solver and the Estimator.

``time.perf_counter`` and ``time.thread_time`` are replaced by one clock that moves only when it is
read (by READ_TICK_S) and when compiled work runs (by WORK_TICK_S per call, per generation for a chunk of
generations); every compiled call the
solvers and the Estimator make (population evaluations and generations, the Levenberg-Marquardt
kernels, the round-off search's evaluations) records the clock when it starts.  A call that starts
after the deadline is work after the deadline: none may.  No wall-clock figure is asserted (the real
overruns are measured by ``glpma-fk bench``, deadline section)."""
import numpy as np
import pytest

from glpma_ros import solvers
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.solvers import driver, lm, local

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


class FakeClock:
    def __init__(self):
        self.now = 1000.0
        self.starts = []            # clock at the start of each compiled call, while recording
        self.recording = False

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


@pytest.fixture
def clock(monkeypatch):
    c = FakeClock()
    monkeypatch.setattr("time.perf_counter", c.read)
    monkeypatch.setattr("time.thread_time", c.read)
    for module, name in ((local, "lm_kernel"), (local, "multistart_kernel"), (lm, "lm_kernel"),
                         (driver, "population_fitness")):
        monkeypatch.setattr(module, name, c.work(getattr(module, name)))
    # step(self, n_generations, term)
    monkeypatch.setattr(driver.EvolutionaryState, "step", c.work(driver.EvolutionaryState.step, per_generation=True))
    return c


def _watch_model(monkeypatch, clock, model):
    """The round-off search evaluates through the model itself."""
    monkeypatch.setattr(model, "fitness", clock.work(model.fitness))


def _late(clock, deadline):
    return [round((t - deadline) * 1e6, 3) for t in clock.starts if t >= deadline]


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_no_solver_works_after_its_deadline(kind, clock, monkeypatch, request):
    model = request.getfixturevalue(kind)
    _watch_model(monkeypatch, clock, model)
    for legs in RPR_CASES if kind == "rpr" else HEX_CASES:
        for name in solvers.SOLVERS:
            for budget in BUDGETS_S[1:]:          # the first evaluation runs whatever the budget
                clock.starts.clear()
                clock.recording = True
                start = clock.now
                solvers.solve(name, model, np.array(legs), rng=0, budget_s=budget, max_evals=10**9)
                clock.recording = False
                assert clock.starts, (name, budget)
                assert not _late(clock, start + budget), (name, legs, budget, "µs late", _late(clock, start + budget))


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
@pytest.mark.parametrize("warm", [False, True])
def test_the_estimator_does_no_work_after_its_deadline(kind, warm, clock, monkeypatch, request):
    """Cold and warm (from a pose far from the legs' assembly, so that every stage runs), on legs with
    and without an assembly: every compiled call starts before the deadline, and the estimate is
    returned within one call's time of it; when the deciding work did not fit, ``budget_exhausted``."""
    model = request.getfixturevalue(kind)
    start_x = request.getfixturevalue("rpr_solutions" if kind == "rpr" else "hex_published")[1] if warm else None
    statuses = set()
    for legs in RPR_CASES if kind == "rpr" else HEX_CASES:
        for budget in BUDGETS_S:
            est = Estimator(model, time_budget_s=budget, initial_pose=start_x, max_evals=10**9)
            _watch_model(monkeypatch, clock, model)
            clock.starts.clear()
            clock.recording = True
            start = clock.now
            e = est.estimate(legs)
            clock.recording = False
            end = clock.now
            deadline = start + budget
            assert not _late(clock, deadline), (legs, budget, e.status, "µs late", _late(clock, deadline))
            assert end <= deadline + WORK_TICK_S + 1000 * READ_TICK_S, (legs, budget, e.status, end - deadline)
            if budget == 0.0:
                assert e.status == "budget_exhausted" and not clock.starts
            statuses.add(e.status)
    assert "budget_exhausted" in statuses and statuses & {"converged", "no_solution"}, statuses
