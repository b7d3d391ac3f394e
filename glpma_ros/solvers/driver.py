"""The loop every evolutionary solver shares: compiled chunks of generations
between which the wall clock is checked, the refinement is scheduled and the
history of the best fitness is recorded."""
from __future__ import annotations

import math
import time

import numpy as np

from ..models.kernels import population_fitness
from ..runtime.collector import HOLD
from . import refine
from .common import BUDGET_EXHAUSTED, CONVERGED, SolveResult, Termination, initial_population, kernel_array

#: generations per compiled call when no deadline limits it
CHUNK_GENERATIONS = 256
#: share of the time left that one chunk of generations may take under a deadline: the clock is read
#: often enough that a mis-estimated time per evaluation stays a small overrun.  A state whose kernel stops
#: itself at the deadline takes this share of the whole budget instead (:attr:`EvolutionaryState.stops_itself`)
CHUNK_SHARE = 0.1
#: an estimate of the time per evaluation (or per refinement iteration) that measures less forgets at most
#: this share of itself per chunk (a slow chunk raises it at once: overrunning is worse than stopping early)
COST_DECAY = 0.5
#: ... and the tail (the Python from the last compiled call to the result) this share per solve: that Python
#: runs two to three times slower while the core's sibling is busy, and a tail longer than its reserve is time
#: past the deadline, while a reserve longer than the tail only ends the search a few microseconds early
TAIL_DECAY = 0.1
#: ... and a compiled call's entry (from Python to the kernel's first clock read: unboxing its arguments, 12-50 us
#: and up to 0.15 ms while the core's sibling is busy) this share per call: the last call of a solve starts only when
#: its entry fits, and an entry longer than its estimate is time past the deadline
ENTRY_DECAY = 0.02
#: the first refinement's time per iteration, in evaluations of the fitness (one residual vector with its
#: Jacobian costs a few evaluations of the fitness; measured on the next refinement)
POLISH_ITERATION_EVALS = 8
#: refine again once the best fitness has improved by this factor since the last try
POLISH_GAIN = 100.0
#: iteration cap of one Levenberg-Marquardt refinement
POLISH_MAX_ITER = 40


class Problem:
    """A model with given leg lengths; counts every evaluation it makes."""

    def __init__(self, model, legs):
        self.model = model
        self.legs = kernel_array(legs)
        self.kind = model.kind_id
        self.data = model.data
        self.n_res = model.n_res

    def evaluate(self, X, term: Termination) -> np.ndarray:
        term.nfev += len(X)
        return population_fitness(kernel_array(X), self.kind, self.data, self.legs, self.n_res)


class EvolutionaryState:
    """A population with its fitness, advanced by a compiled kernel."""

    name = "evolution"

    def __init__(self, problem, pop, fit, rng):
        self.problem = problem
        self.pop = kernel_array(pop)
        self.fit = kernel_array(fit)
        self.rng = rng
        #: the ``time.perf_counter()`` value by which the compiled calls of a chunk must end (the deadline less
        #: the Python that follows the last one), set by the driver before each chunk; None: no deadline
        self.work_deadline = None
        #: the last compiled call stopped at ``work_deadline`` (kernels that read the clock themselves set it)
        self.out_of_time = False

    #: the compiled call reads the clock between two steps of a few microseconds and stops at ``work_deadline``:
    #: its chunk's size decides how often the driver may refine between chunks, not how far it may overrun, so
    #: it is sized by the budget (:meth:`Costs.generations`); sized by the time left, the last chunks before
    #: the deadline would be a generation each, each paying a compiled call's fixed cost (12-50 µs measured,
    #: several generations of work) and ending on the driver's longer way to the result
    stops_itself = False
    #: the last compiled call's time from Python to its kernel's first read of the clock (the call's fixed cost:
    #: its arguments unboxed, a ``numpy.random.Generator``'s the most), which no clock check inside the kernel
    #: bounds; set by states whose kernel reports its entry under a deadline (0: not measured)
    entry_s = 0.0

    def best(self):
        i = int(np.argmin(self.fit))
        return self.pop[i].copy(), float(self.fit[i])

    def inject(self, x, f):
        """Put ``x`` in place of the worst individual."""
        i = int(np.argmax(self.fit))
        self.pop[i] = x
        self.fit[i] = f

    def evals_per_generation(self) -> int:
        return len(self.pop)

    def evals_in(self, n_generations: int) -> int:
        """The most evaluations a chunk of ``n_generations`` may make: what its time is sized by."""
        return n_generations * self.evals_per_generation()

    def advance(self, n_generations, max_evals, tolerance):  # pragma: no cover - abstract
        raise NotImplementedError

    def step(self, n_generations, term: Termination):
        gens, evals = self.advance(int(n_generations), term.evals_left(), term.tolerance)
        term.nfev += int(evals)
        return int(gens)


def run_evolution(name, model, legs, make_state, rng, *, tolerance, max_evals, budget_s, polish, center=None,
                  start=None):
    """Run ``make_state(problem, term)``'s population to termination.

    A warm start's first individual is the previous estimate ``center``: with the
    refinement on it is polished before the rest of the population is drawn, and
    when that converges the population is never needed (the node's usual case).
    With redundant legs (more than the degrees of freedom) measured legs leave a residual, so the
    fitness never reaches ``tolerance``: a refinement that converges to the least-squares pose ends
    the search instead.

    The deadline (``budget_s`` from ``start``, a ``time.perf_counter()`` value, default now) is
    hard: every compiled call is sized by the measured cost of the work (:class:`Costs`: the thread's CPU
    time per evaluation, first from the initial population's evaluation, then from every chunk) so that it
    is expected to end before the deadline; a chunk of generations takes at most :data:`CHUNK_SHARE` of the
    time left (of the budget, for a kernel that stops itself at the deadline) and starts only when one
    generation still fits, a refinement's iteration cap is cut to the
    iterations that fit, both before the deadline less the measured tail (the Python that builds the
    result).  The search therefore returns by its deadline plus the error of that estimate on one compiled
    call.  The first population's evaluation runs whatever the budget (a result needs a point).
    Under a deadline Python's garbage collector is held off until the search returns
    (:data:`~glpma_ros.runtime.collector.HOLD`): its pauses, between two clock checks, are not bounded by them.
    """
    if budget_s is None:
        return _evolve(name, model, legs, make_state, rng, tolerance=tolerance, max_evals=max_evals,
                       budget_s=budget_s, polish=polish, center=center, start=start)
    HOLD.acquire()
    try:
        return _evolve(name, model, legs, make_state, rng, tolerance=tolerance, max_evals=max_evals,
                       budget_s=budget_s, polish=polish, center=center, start=start)
    finally:
        HOLD.release()


def _evolve(name, model, legs, make_state, rng, *, tolerance, max_evals, budget_s, polish, center, start):
    """:func:`run_evolution`'s search."""
    least_squares = polish and model.redundancy > 0
    term = Termination(tolerance=tolerance, max_evals=max_evals, budget_s=budget_s, start=start)
    problem = Problem(model, legs)
    history = []
    nit = 0
    polished = False
    last_polish_f = np.inf
    refined = None              # best refinement result (a stationary point unless cut short)
    warm = None
    costs = Costs(term, name, model)
    if polish and center is not None:
        warm = costs.polish(model, np.asarray(center, dtype=float), problem.legs, rng, tolerance)
        refined = warm[:2] if math.isfinite(warm[1]) else None
        if warm[1] < tolerance or (least_squares and warm.converged):
            history.append((term.nfev, warm[1]))
            costs.keep()
            return _result(name, model, warm[0], warm[1], term, nit, True, history, refined, CONVERGED)
    c0, nfev0 = time.thread_time(), term.nfev
    state = make_state(problem, term)
    last_work = time.thread_time()              # the end of the last compiled call: the tail counts from it
    costs.note_evals(last_work - c0, term.nfev - nfev0)
    if warm is not None and warm[1] < state.best()[1]:
        state.inject(warm[0], warm[1])
        last_polish_f = warm[1]
    x, f = state.best()
    stop = None
    cut = False             # the last compiled call stopped at the work deadline
    while True:
        x, f = state.best()
        if polish and f * POLISH_GAIN < last_polish_f and term.status(f) is None:
            last_polish_f = f
            xp, fp, n, reached = costs.polish(model, x, problem.legs, rng, tolerance)
            last_work = time.thread_time()
            if math.isfinite(fp) and (refined is None or fp < refined[1]):
                refined = (xp, fp)
            if fp < f:
                state.inject(xp, fp)
                x, f, polished = xp, fp, True
                last_polish_f = min(last_polish_f, fp)
            if least_squares and reached:
                stop = CONVERGED
        history.append((term.nfev, f))
        stop = stop or term.status(f)
        if stop is not None:
            break
        if term.deadline is None:
            chunk = CHUNK_GENERATIONS
        else:
            chunk = costs.generations(state)
            if chunk == 0:                      # not even one generation fits: stop at the deadline
                stop = BUDGET_EXHAUSTED
                break
        if term.deadline is not None:
            state.work_deadline = term.deadline - costs.tail_s
        c0, nfev = time.thread_time(), term.nfev
        gens = state.step(chunk, term)
        last_work = time.thread_time()
        costs.note_evals(last_work - c0, term.nfev - nfev)
        costs.note_entry(state.entry_s)
        costs.on_chunks = costs.on_chunks or term.nfev > nfev
        nit += gens
        if state.out_of_time:
            # the compiled call stopped at the work deadline: nothing more fits (no refinement, no chunk), and
            # the Python from here to the result is the tail the deadline left room for: straight to the result
            cut = True
            break
        if term.nfev == nfev and term.status(state.best()[1]) is None:
            break  # fewer evaluations left than one generation needs
        polished = polished and state.best()[1] >= f
    x_end, f_end = state.best()
    if cut:
        polished = polished and f_end >= f
        history.append((term.nfev, f_end))
        stop = term.status(f_end) or BUDGET_EXHAUSTED
    x, f = x_end, f_end
    result = _result(name, model, x, f, term, nit, polished, history, refined,
                     stop if stop in (CONVERGED, BUDGET_EXHAUSTED) else None)
    costs.note_tail(time.thread_time() - last_work)
    costs.keep()
    return result


#: the costs measured by the last solve under a deadline, per solver and model (kind, legs): the next solve's
#: first estimates, before it has measured its own (the compiled work costs the same from one solve to the
#: next; a generation of one solver costs per evaluation what another's does not)
_LAST_COSTS: dict = {}


class GenerationInProgress(EvolutionaryState):
    """An evolutionary state whose compiled generation may stop between two children at the deadline and
    resume at the next call: the children made so far in ``new`` / ``new_f`` (the elite first), their count in
    ``progress[0]`` (0: no generation in progress).  Subclasses allocate the three."""

    new: np.ndarray
    new_f: np.ndarray
    progress: np.ndarray

    def best(self):
        """Best of the population and of the children of the generation in progress."""
        x, f = super().best()
        k = int(self.progress[0])
        if k:
            i = int(np.argmin(self.new_f[:k]))
            if self.new_f[i] < f:
                return self.new[i].copy(), float(self.new_f[i])
        return x, f

    def inject(self, x, f):
        """Into the population's worst slot, and as the elite of the generation in progress."""
        super().inject(x, f)
        if self.progress[0] and f < self.new_f[0]:
            self.new[0] = x
            self.new_f[0] = f


class Costs:
    """The measured cost of the compiled work under a deadline, which sizes every compiled call so that it
    is expected to end before the deadline: the thread's CPU time (``time.thread_time``: the work itself,
    not the time other processes took the core meanwhile) per evaluation of the fitness and per iteration
    of the refinement, and the *tail*: the Python from the end of the last compiled call to the result,
    which the compiled work leaves room for before the deadline.  Each estimate is the latest measure, or
    :data:`COST_DECAY` (the tail: :data:`TAIL_DECAY`) less than the previous estimate when that is larger."""

    def __init__(self, term: Termination, name: str, model):
        self.term = term
        self.key = (name, model.kind, model.n_legs)
        # s per fitness evaluation (0: not measured yet), s per refinement iteration (None: not measured yet)
        # s of Python from the end of the last compiled call to the result (0: not measured yet)
        # s from Python to a chunk's kernel reading the clock (0: not measured)
        self.per_eval, self.per_iteration, self.tail_s, self.entry_s = _LAST_COSTS.get(self.key,
                                                                                      (0.0, None, 0.0, 0.0))
        # the time per evaluation was measured on a chunk of generations (the initial population's evaluation
        # alone, one vectorised call, says nothing of what a generation adds around its evaluations)
        self.on_chunks = self.key in _LAST_COSTS

    def keep(self) -> None:
        """These estimates become the next solve's first ones."""
        if self.term.deadline is not None and self.on_chunks:
            _LAST_COSTS[self.key] = (self.per_eval, self.per_iteration, self.tail_s, self.entry_s)

    @staticmethod
    def _track(old, seconds, decay=COST_DECAY):
        return max(seconds, (1.0 - decay) * old) if old else seconds

    def note_evals(self, seconds: float, evals: int) -> None:
        if evals > 0:
            self.per_eval = self._track(self.per_eval, seconds / evals)

    def note_entry(self, seconds: float) -> None:
        if seconds > 0.0:
            self.entry_s = self._track(self.entry_s, seconds, ENTRY_DECAY)

    def note_tail(self, seconds: float) -> None:
        self.tail_s = self._track(self.tail_s, seconds, TAIL_DECAY)

    def left(self) -> float:
        """Seconds to the deadline less the tail: what compiled work may still fill."""
        return self.term.deadline - self.tail_s - time.perf_counter()

    def generations(self, state) -> int:
        """Generations of the next chunk: as many as fit in :data:`CHUNK_SHARE` of the time left (a state that
        :attr:`~EvolutionaryState.stops_itself`: of the budget, within the time left; at most
        :data:`CHUNK_GENERATIONS`; one until a chunk has been measured), at least one; 0 when not even one fits
        before the deadline (after the call's measured entry, :attr:`EvolutionaryState.entry_s`)."""
        left = self.left()
        if self.entry_s + self.per_eval * state.evals_in(1) > left:
            return 0
        if not self.on_chunks:
            return 1
        room = min(CHUNK_SHARE * self.term.budget_s, left) if state.stops_itself else CHUNK_SHARE * left
        n = 1
        while n < CHUNK_GENERATIONS and self.per_eval * state.evals_in(2 * n) <= room:
            n *= 2
        return min(n, CHUNK_GENERATIONS)

    def polish(self, model, x, legs, rng, tolerance) -> refine.Polished:
        """:func:`.refine.polish` with the iterations that fit before the deadline (at most
        :data:`POLISH_MAX_ITER`; none fit: nothing is computed, ``x`` comes back with an infinite fitness);
        its round-off search stops one round of it before the deadline.  Counts its evaluations."""
        max_iter, deadline = POLISH_MAX_ITER, self.term.deadline
        if deadline is not None:
            deadline -= self.tail_s                                     # the Python after the last call
            per_iteration = self.per_iteration
            if per_iteration is None:
                per_iteration = POLISH_ITERATION_EVALS * self.per_eval
            # a round of the round-off search: as measured, or its evaluations before any was
            deadline -= max(refine.round_s(model), refine.GRID_CANDIDATES * self.per_eval)
            left = deadline - time.perf_counter()
            if per_iteration > 0.0:
                max_iter = min(max_iter, int(left / per_iteration))
            if max_iter < 1:
                return refine.Polished(np.ascontiguousarray(x, dtype=float).reshape(-1).copy(), math.inf, 0, False)
        c0 = time.thread_time()
        p = refine.polish(model, x, legs, rng, tolerance=tolerance, max_iter=max_iter, deadline=deadline)
        if p.nfev > 0 and deadline is not None:
            # per iteration of the Levenberg-Marquardt (at most max_iter), the round-off search's cheaper
            # evaluations included: what the next cap divides the time left by
            self.per_iteration = self._track(self.per_iteration or 0.0,
                                             (time.thread_time() - c0) / min(p.nfev, max(max_iter, 1)))
        self.term.nfev += p.nfev
        return p


MESSAGES = {"converged": "fitness below tolerance", "budget_exhausted": "time budget exhausted",
            "max_evals": "evaluation cap reached"}


def _result(name, model, x, f, term, nit, polished, history, refined=None, status=None) -> SolveResult:
    status = status or term.final_status(f)
    return SolveResult(x=model.canonical(x), fun=f, nfev=term.nfev, nit=nit, elapsed_s=term.elapsed(),
                       status=status, solver=name, polished=polished and status == CONVERGED,
                       history=history, message=MESSAGES[status],
                       refined_x=None if refined is None else refined[0])


def solve_population(name, model, legs, make_population, *, population, rng, init_range, center, spread,
                     tolerance, max_evals, budget_s, polish, sample=initial_population, start=None):
    """What every population solver's ``solve`` does: draw ``population`` individuals with
    ``sample(rng, size, n_vars, init_range, center, spread)``, evaluate them, hand them to
    ``make_population(problem, pop, fit, rng, term)`` and run that to termination."""
    rng = np.random.default_rng(rng)

    def make(problem, term):
        pop = sample(rng, population, model.n_vars, init_range, center, spread)
        return make_population(problem, pop, problem.evaluate(pop, term), rng, term)

    return run_evolution(name, model, legs, make, rng, tolerance=tolerance, max_evals=max_evals,
                         center=center, budget_s=budget_s, polish=polish, start=start)
