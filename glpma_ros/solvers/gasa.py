"""Hybrid GA-SA: a genetic algorithm whose mutation is replaced by simulated
annealing of each child (Chandra, Zhang & Rolland 2009, "Solving the forward
kinematics of the 3RPR planar parallel manipulator using a hybrid
meta-heuristic paradigm", CIRA 2009 -- paper 004, Algorithm 1 and section
IV.A item 4; first used for the 6-6 manipulator by Chandra, Frean & Rolland 2009).

Generational.  Each generation (004 Algorithm 1):

* **elitism** -- the best individual is copied unchanged (004 section IV.A:
  "roulette wheel selection is used in conjunction with the elitist strategy");
* for each other slot: **roulette-wheel selection** of two parents (the RCGA's
  weights ``1 / f``, :func:`rcga.roulette_cumulative`), **Wright's heuristic
  crossover** into a single child with probability ``crossover_rate = 0.9``
  (:func:`rcga.wright_crossover`; otherwise the child is a copy of the first
  parent), then, with probability ``sa_rate = 0.9`` and *in place of
  mutation*, the child is presented to **simulated annealing** for
  ``sa_iterations = 500`` iterations (Markov chains, :func:`sa.anneal`) of
  ``chain_length = 20`` proposals, from the current initial temperature with
  cooling rate 0.01 per chain; the best point the annealer visits is the
  child copied into the new population (Algorithm 1 steps 4-5);
* **"Lower the initial temperature T"** (Algorithm 1 step 6, inside the loop
  over children): after each child the annealer's initial temperature, 10 at
  the start of the run, is multiplied by ``1 - cooling_rate``.  It is not reset
  between generations.  Read this way the last annealing temperature of the
  ``k``-th child is ``10 x 0.99^(k + 499)``, which reaches the 1e-4 scale of
  004's stopping rule after ~650 children: 16-18 generations of 40, the
  published 18 +- 3 (without step 6 the annealer would end every child at
  T ~ 0.07 and the run would not get below f ~ 1e-2).

**"N of 500 iterations"** is read in the unit 004's Table II uses for SA
("No. Itera" hardly changes with the chain length while the CPU time grows
with it, see :mod:`.sa`): 500 Markov chains of 20, i.e. 10,000 proposals per
annealed child.  004 does not settle it; the other reading, 500 proposals
(``sa_iterations=25``), is a parameter away (BENCHMARKS.md compares both
readings with 004 Table II).

One "iteration" in 004 Table II's sense is one GA generation.  The annealer's
neighbourhood follows the law of :mod:`.sa`: ``b(T) = b0 sqrt(T / T0_SA)``,
``b0`` half the initial range at the SA baseline's ``T0_SA = 100``, so at the
hybrid's T = 10 the proposals are ``sqrt(0.1)`` of that (004 gives no ``b``).

Evaluation counting: a crossover child costs one evaluation, every annealing
proposal one; a copied child that is not annealed costs none.  A generation cut
short by the evaluation cap or by reaching the tolerance keeps the previous
individuals in the slots it did not fill, and counts as one generation.
Under a deadline the wall clock is checked every ``DEADLINE_CHAINS`` Markov
chains, not once per annealed child.
"""
from __future__ import annotations

import time

import numpy as np
from numba import njit

from ..models.kernels import fitness_one
from . import sa
from .driver import GenerationInProgress, solve_population
from .rcga import CROSSOVER_RATE, crossover_or_copy, mutation_width, start_generation

#: 004 section IV.A item 4: "initial temperature of 10"
T0 = 10.0
#: 004 section IV.A item 4 and IV.B: "N of 500 iterations" of SA per child
SA_ITERATIONS = 500
#: 004 section IV.A item 4: "Markov chain length of 20"
CHAIN_LENGTH = 20
#: 004 section IV.A item 4: "cooling rate of 0.01" (per chain, and per child for step 6)
COOLING_RATE = 0.01
#: 004 section IV.A item 4: "The SA is used as a genetic operator and applied at the rate of 0.9"
SA_RATE = 0.9
#: 004 section IV.A: "The population size of 40"
POPULATION = 40
#: Markov chains per compiled call when no deadline limits it
UNLIMITED = 2**62
#: Markov chains per compiled call under a deadline: 100 proposals, tens of microseconds,
#: so the clock is read often enough to stop within a fraction of a millisecond
DEADLINE_CHAINS = 5


@njit(cache=True, error_model="numpy")
def _finish_child(pop, fit, new, new_f, progress, child, cf, tolerance, evals, max_evals):
    """Put a finished child in the generation in progress; commit the generation when
    it is full, when the child reaches ``tolerance`` or when ``max_evals`` is spent (then
    the unfilled slots keep the previous individuals).  Returns 1 if it committed."""
    i = progress[0]
    new[i] = child
    new_f[i] = cf
    progress[0] = i + 1
    N = pop.shape[0]
    if progress[0] == N or cf < tolerance or evals >= max_evals:
        for k in range(progress[0], N):
            new[k] = pop[k]
            new_f[k] = fit[k]
        pop[:] = new
        fit[:] = new_f
        progress[0] = 0
        return 1
    return 0


@njit(cache=True, error_model="numpy")
def gasa_generations(pop, fit, new, new_f, cum, progress, child, child_best, child_state, rng, n_generations,
                     max_chains, max_evals, tolerance, temperature, t_ref, b_ref, sa_iterations, chain_length,
                     cooling_rate, crossover_rate, sa_rate, kind, data, legs, n_res):
    """Evolve ``pop``/``fit`` in place, child by child and Markov chain by chain.

    ``new``/``new_f`` hold the generation in progress and ``progress[0]`` the
    number of its slots already filled (0: none started); ``progress[1]`` is 1
    while a child is being annealed, its state in ``child``, ``child_best`` and
    ``child_state = [f, best f, chain temperature, chains done]``.  So a call
    may stop after ``max_chains`` Markov chains and the next one resume exactly
    where it stopped (the driver's deadline; the random stream is the same as
    in one long call).  Returns (generations completed, evaluations, initial
    temperature for the next child)."""
    r = np.empty(n_res)
    gens = 0
    evals = 0
    chains = 0
    while gens < n_generations and evals < max_evals and chains < max_chains:
        if progress[1] == 0:                       # start a child
            if progress[0] == 0:                   # start a generation
                if not start_generation(pop, fit, cum, new, new_f, tolerance):
                    break
                progress[0] = 1
            parent = crossover_or_copy(pop, fit, cum, rng, crossover_rate, child)
            if parent < 0:
                cf = fitness_one(child, kind, data, legs, r)
                evals += 1
            else:
                cf = fit[parent]
            if rng.random() >= sa_rate:            # not annealed: the child as it is
                temperature *= 1.0 - cooling_rate  # Algorithm 1 step 6
                gens += _finish_child(pop, fit, new, new_f, progress, child, cf, tolerance, evals, max_evals)
                continue
            child_best[:] = child
            child_state[0] = cf
            child_state[1] = cf
            child_state[2] = temperature
            child_state[3] = 0.0
            progress[1] = 1
        # anneal the child in progress, at most the chains this call has left
        k = min(sa_iterations - int(child_state[3]), max_chains - chains)
        f, best_f, e, t_after = sa.anneal(child, child_state[0], child_best, child_state[1], child_state[2], t_ref,
                                          b_ref, k, chain_length, cooling_rate, max_evals - evals, tolerance, rng,
                                          kind, data, legs, n_res)
        evals += e
        chains += k
        child_state[0] = f
        child_state[1] = best_f
        child_state[2] = t_after
        child_state[3] += k
        if int(child_state[3]) >= sa_iterations or best_f < tolerance or evals >= max_evals:
            progress[1] = 0
            temperature *= 1.0 - cooling_rate      # Algorithm 1 step 6
            gens += _finish_child(pop, fit, new, new_f, progress, child_best, best_f, tolerance, evals, max_evals)
    return gens, evals, temperature


class GASAPopulation(GenerationInProgress):
    """The population, with the generation and the annealed child in progress
    alongside it.  Under a deadline (``term.deadline``) the compiled kernel runs
    ``DEADLINE_CHAINS`` Markov chains per call and the clock is checked in between:
    one annealed child is 10,000 evaluations and a generation ~390,000, far longer
    than a real-time budget."""

    name = "gasa"

    def __init__(self, problem, pop, fit, rng, *, width, term=None, t0=T0, sa_iterations=SA_ITERATIONS,
                 chain_length=CHAIN_LENGTH, cooling_rate=COOLING_RATE, crossover_rate=CROSSOVER_RATE,
                 sa_rate=SA_RATE, neighbour_fraction=sa.NEIGHBOUR_FRACTION):
        super().__init__(problem, pop, fit, rng)
        self.term = term
        self.temperature = float(t0)
        self.sa_iterations, self.chain_length = int(sa_iterations), int(chain_length)
        self.cooling_rate, self.crossover_rate = float(cooling_rate), float(crossover_rate)
        self.sa_rate = float(sa_rate)
        width = np.broadcast_to(np.asarray(width, dtype=float), (pop.shape[1],))
        self.b_ref = np.ascontiguousarray(float(neighbour_fraction) * width)
        if not (self.temperature > 0 and self.sa_iterations >= 1 and self.chain_length >= 1
                and 0 <= self.cooling_rate < 1 and len(pop) >= 2):
            raise ValueError("GA-SA needs t0 > 0, sa_iterations >= 1, chain_length >= 1, "
                             "0 <= cooling_rate < 1 and a population of at least 2")
        self.new = np.empty_like(self.pop)
        self.new_f = np.empty_like(self.fit)
        self.cum = np.empty_like(self.fit)
        self.progress = np.zeros(2, dtype=np.int64)      # slots filled, child being annealed
        self.child = np.empty(pop.shape[1])
        self.child_best = np.empty(pop.shape[1])
        self.child_state = np.zeros(4)

    def evals_per_generation(self) -> int:
        return (len(self.pop) - 1) * (1 + self.sa_iterations * self.chain_length)

    def evals_in(self, n_generations: int) -> int:
        """Under a deadline a chunk is as many compiled calls of :data:`DEADLINE_CHAINS` chains as fit (the clock
        is read between them): its first call is what must fit."""
        if self.term is None or self.term.deadline is None:
            return super().evals_in(n_generations)
        return min(super().evals_in(n_generations), DEADLINE_CHAINS * self.chain_length)

    def _run(self, n_generations, max_chains, max_evals, tolerance):
        p = self.problem
        gens, evals, self.temperature = gasa_generations(
            self.pop, self.fit, self.new, self.new_f, self.cum, self.progress, self.child, self.child_best,
            self.child_state, self.rng, n_generations, max_chains, max_evals, tolerance, self.temperature, sa.T0,
            self.b_ref, self.sa_iterations, self.chain_length, self.cooling_rate, self.crossover_rate, self.sa_rate,
            p.kind, p.data, p.legs,
            p.n_res)
        return gens, evals

    def advance(self, n_generations, max_evals, tolerance):
        if self.term is None or self.term.deadline is None:
            return self._run(n_generations, UNLIMITED, max_evals, tolerance)
        deadline = self.term.deadline if self.work_deadline is None else self.work_deadline
        self.out_of_time = False
        gens = evals = 0
        call_s = 0.0            # the longest call so far (the thread's CPU time): the next starts only if it fits
        while gens < n_generations and evals < max_evals:
            if time.perf_counter() + call_s >= deadline:
                self.out_of_time = True     # the next call would end past the work deadline: nothing more fits
                break
            c0 = time.thread_time()
            g, e = self._run(n_generations - gens, DEADLINE_CHAINS, max_evals - evals, tolerance)
            call_s = max(call_s, time.thread_time() - c0)
            gens += g
            evals += e
            if g == 0 and e == 0 and self.progress[0] == 0:
                break  # converged: nothing left to do
        return gens, evals


def default_population(model) -> int:
    """004's population of 40."""
    return POPULATION


def solve(model, legs, *, population=POPULATION, rng=None, init_range=(-50.0, 50.0), center=None, spread=None,
          tolerance=1e-20, max_evals=10_000, budget_s=None, start=None, polish=True, **params):
    """Minimise the model's fitness with the hybrid GA-SA (plus the refinement
    unless ``polish=False``).  ``params``: ``t0``, ``sa_iterations``,
    ``chain_length``, ``cooling_rate``, ``crossover_rate``, ``sa_rate``,
    ``neighbour_fraction``."""
    return solve_population("gasa", model, legs, lambda problem, pop, fit, rng, term: GASAPopulation(
        problem, pop, fit, rng, width=mutation_width(init_range, spread, model.n_vars), term=term, **params),
                            population=population, rng=rng, init_range=init_range, center=center, spread=spread,
                            tolerance=tolerance, max_evals=max_evals, budget_s=budget_s, polish=polish, start=start)
