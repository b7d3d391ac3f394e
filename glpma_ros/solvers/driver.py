"""The loop every evolutionary solver shares: compiled chunks of generations
between which the wall clock is checked, the refinement is scheduled and the
history of the best fitness is recorded."""
from __future__ import annotations

import math
import time

import numpy as np

from ..models.kernels import population_fitness
from . import refine
from .common import BUDGET_EXHAUSTED, CONVERGED, SolveResult, Termination, initial_population

#: generations per compiled call when no deadline limits it
CHUNK_GENERATIONS = 256
#: generations of the first chunk under a deadline (timing probe)
PROBE_GENERATIONS = 4
#: refine again once the best fitness has improved by this factor since the last try
POLISH_GAIN = 100.0
#: iteration cap of one Levenberg-Marquardt refinement
POLISH_MAX_ITER = 40


class Problem:
    """A model with given leg lengths; counts every evaluation it makes."""

    def __init__(self, model, legs):
        self.model = model
        self.legs = np.ascontiguousarray(legs, dtype=float)
        self.kind = model.kind_id
        self.data = model.data
        self.n_res = model.n_res

    def evaluate(self, X, term: Termination) -> np.ndarray:
        term.nfev += len(X)
        return population_fitness(np.ascontiguousarray(X), self.kind, self.data, self.legs, self.n_res)


class EvolutionaryState:
    """A population with its fitness, advanced by a compiled kernel."""

    name = "evolution"

    def __init__(self, problem, pop, fit, rng):
        self.problem = problem
        self.pop = np.ascontiguousarray(pop, dtype=float)
        self.fit = np.ascontiguousarray(fit, dtype=float)
        self.rng = rng

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

    def first_chunk(self) -> int:
        """Generations of the first chunk under a deadline, which measures the time per generation: enough
        to hold every kind of work a generation may bring (:data:`PROBE_GENERATIONS` by default)."""
        return PROBE_GENERATIONS

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
    hard: a chunk of generations starts only when at least one generation is expected to fit before
    it (``seconds_per_gen`` measured on the chunks so far), so that the search returns by its deadline
    plus at most one generation's time.  The first population's evaluation runs whatever the budget
    (a result needs a point).
    """
    least_squares = polish and model.redundancy > 0
    term = Termination(tolerance=tolerance, max_evals=max_evals, budget_s=budget_s, start=start)
    problem = Problem(model, legs)
    history = []
    nit = 0
    polished = False
    last_polish_f = np.inf
    refined = None              # best refinement result (a stationary point unless cut short)
    warm = None
    if polish and center is not None:
        warm = refine.polish(model, np.asarray(center, dtype=float), problem.legs, rng, tolerance=tolerance,
                             max_iter=POLISH_MAX_ITER, deadline=term.deadline)
        term.nfev += warm[2]
        refined = warm[:2] if math.isfinite(warm[1]) else None
        if warm[1] < tolerance or (least_squares and warm.converged):
            history.append((term.nfev, warm[1]))
            return _result(name, model, warm[0], warm[1], term, nit, True, history, refined, CONVERGED)
    state = make_state(problem, term)
    if warm is not None and warm[1] < state.best()[1]:
        state.inject(warm[0], warm[1])
        last_polish_f = warm[1]
    seconds_per_gen = None
    x, f = state.best()
    stop = None
    while True:
        x, f = state.best()
        if polish and f * POLISH_GAIN < last_polish_f and term.status(f) is None:
            last_polish_f = f
            xp, fp, n, reached = refine.polish(model, x, problem.legs, rng, tolerance=tolerance,
                                               max_iter=POLISH_MAX_ITER, deadline=term.deadline)
            term.nfev += n
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
        if term.deadline is None or seconds_per_gen is None:
            chunk = CHUNK_GENERATIONS if term.deadline is None else state.first_chunk()
        else:
            left = term.deadline - time.perf_counter()
            if left < seconds_per_gen:          # not even one generation fits: stop at the deadline
                stop = BUDGET_EXHAUSTED
                break
            chunk = int(max(1, min(CHUNK_GENERATIONS, 0.1 * left / seconds_per_gen)))
        t0 = time.perf_counter()
        nfev = term.nfev
        gens = state.step(chunk, term)
        if gens:
            seconds_per_gen = (time.perf_counter() - t0) / gens
        nit += gens
        if term.nfev == nfev and term.status(state.best()[1]) is None:
            break  # fewer evaluations left than one generation needs
        polished = polished and state.best()[1] >= f
    x, f = state.best()
    return _result(name, model, x, f, term, nit, polished, history, refined,
                   stop if stop in (CONVERGED, BUDGET_EXHAUSTED) else None)


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
