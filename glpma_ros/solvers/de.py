"""Differential evolution, DE/rand/1/bin, as used for pose tracking by Funes Lora
et al. (2018), "Metaheuristic techniques comparison to optimize robotic
end-effector behavior and its workspace", IJARS (paper 003: Algorithm 1 and
Eq. 21-23; after Storn & Price 1997).

Each generation, for every target vector ``x_i``:

1. **mutation** -- three distinct individuals ``r0, r1, r2`` (all different
   from ``i``) drawn at random: ``v = x_r0 + F (x_r1 - x_r2)``;
2. **binomial crossover** -- ``u_j = v_j`` if ``rand(0, 1) <= CR`` or
   ``j = j_rand`` (one random variable always comes from ``v``), else ``x_ij``;
3. **selection** -- ``u`` replaces ``x_i`` in the next generation when
   ``f(u) <= f(x_i)`` (all trials are made from the current generation, then
   selected: synchronous DE).

``F`` and ``CR`` are **dithered once per generation** (003 Eq. 21-22, the
subscript ``g`` of ``rand_g``): ``F = F_l + rand_g (F_h - F_l)`` with
``[F_l, F_h] = [0.5, 1.0]`` and ``CR = Cr_l + rand_g (Cr_h - Cr_l)`` with
``[Cr_l, Cr_h] = [0.8, 1.0]``.  Population ``Np = 10 D`` (Eq. 23) unless given.

**Warm start** (Algorithm 1 steps 1-2 and 21): the previous pose ``center`` is
individual 0 of the initial population.  With ``spread`` the others are drawn
around it (as every solver here); without ``spread`` they are uniform in
``init_range``, 003's random initialisation plus the injected pose.

003 bounds its variables (Algorithm 1 step 6, Table 4 "Range"); the
forward-kinematics search here is unbounded, as in the other solvers, so no
bound handling is applied.  Evaluation counting: ``Np`` per generation; a
generation runs only when the evaluation cap allows all of it.  Under a deadline the
compiled generations read the clock between blocks of trials and stop at it (the
trials evaluated so far selected), as the RCGA's and G3-PCX's do.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..models.kernels import population_fitness
from ..runtime.clock import kernel_end, reached
from .common import initial_population
from .driver import EvolutionaryState, solve_population

#: 003 Eq. 21 and text: "the range of the mutation scale factor F is [0.5, 1.0]"
F_LOW, F_HIGH = 0.5, 1.0
#: 003 Eq. 22 and text: "a crossover rate interval of [0.8, 1.0]"
CR_LOW, CR_HIGH = 0.8, 1.0
#: 003 Eq. 23: Np = 10 D
POPULATION_PER_VARIABLE = 10
#: DE/rand/1 needs the target and three other distinct individuals
MIN_POPULATION = 4
#: trials evaluated between two reads of the clock under a deadline: a few microseconds of work (a trial's
#: evaluation is 0.3-1 µs on the 3-RPR and the hexapod), while a read costs about 0.1 µs
CLOCK_STRIDE = 8


@njit(cache=True, error_model="numpy")
def de_generations(pop, fit, rng, n_generations, max_evals, tolerance, end, f_low, f_high, cr_low, cr_high,
                   kind, data, legs, n_res):
    """Evolve ``pop``/``fit`` in place; returns (generations completed, evaluations, stopped by the clock).

    A generation's trials are all made from the current population, then evaluated :data:`CLOCK_STRIDE` at a
    time, the clock read before each block: once it reads ``end`` (the kernels' clock,
    :func:`~glpma_ros.runtime.clock.kernel_end`; ``inf``: never) the call stops there, the trials evaluated so far
    selected against their targets (each replaces its own target only: the population stays one of DE's)."""
    N, n = pop.shape
    trial = np.empty_like(pop)
    trial_f = np.empty(N)
    gens = 0
    evals = 0
    while gens < n_generations and evals + N <= max_evals:
        if np.min(fit) < tolerance:
            break
        F = f_low + rng.random() * (f_high - f_low)
        CR = cr_low + rng.random() * (cr_high - cr_low)
        for i in range(N):
            r0 = i
            while r0 == i:
                r0 = rng.integers(0, N)
            r1 = i
            while r1 == i or r1 == r0:
                r1 = rng.integers(0, N)
            r2 = i
            while r2 == i or r2 == r0 or r2 == r1:
                r2 = rng.integers(0, N)
            j_rand = rng.integers(0, n)
            for j in range(n):
                if rng.random() <= CR or j == j_rand:
                    trial[i, j] = pop[r0, j] + F * (pop[r1, j] - pop[r2, j])
                else:
                    trial[i, j] = pop[i, j]
        done = 0
        while done < N and not reached(end):
            block = min(done + CLOCK_STRIDE, N)
            trial_f[done:block] = population_fitness(trial[done:block], kind, data, legs, n_res)
            done = block
        evals += done
        for i in range(done):
            if trial_f[i] <= fit[i]:
                pop[i] = trial[i]
                fit[i] = trial_f[i]
        if done < N:
            return gens, evals, True
        gens += 1
    return gens, evals, False


class DEPopulation(EvolutionaryState):
    name = "de"

    def __init__(self, problem, pop, fit, rng, *, f_low=F_LOW, f_high=F_HIGH, cr_low=CR_LOW, cr_high=CR_HIGH):
        super().__init__(problem, pop, fit, rng)
        self.f_low, self.f_high, self.cr_low, self.cr_high = float(f_low), float(f_high), float(cr_low), float(cr_high)
        if len(pop) < MIN_POPULATION:
            raise ValueError(f"DE/rand/1 needs a population of at least {MIN_POPULATION}")
        if not (0 < self.f_low <= self.f_high and 0 <= self.cr_low <= self.cr_high <= 1):
            raise ValueError("DE needs 0 < f_low <= f_high and 0 <= cr_low <= cr_high <= 1")

    def advance(self, n_generations, max_evals, tolerance):
        p = self.problem
        gens, evals, self.out_of_time = de_generations(self.pop, self.fit, self.rng, n_generations, max_evals,
                                                       tolerance, kernel_end(self.work_deadline), self.f_low,
                                                       self.f_high, self.cr_low, self.cr_high, p.kind, p.data,
                                                       p.legs, p.n_res)
        return gens, evals


def default_population(model) -> int:
    """003 Eq. 23: ``Np = 10 D``."""
    return POPULATION_PER_VARIABLE * model.n_vars


def initial_de_population(rng, size, n_vars, init_range, center=None, spread=None):
    """003 Algorithm 1 steps 1-2: random initial population with the previous
    pose ``center`` as individual 0."""
    if center is not None and spread is None:
        pop = initial_population(rng, size, n_vars, init_range)
        pop[0] = np.asarray(center, dtype=float)
        return pop
    return initial_population(rng, size, n_vars, init_range, center, spread)


def solve(model, legs, *, population=None, rng=None, init_range=(-50.0, 50.0), center=None, spread=None,
          tolerance=1e-20, max_evals=10_000, budget_s=None, start=None, polish=True, **params):
    """Minimise the model's fitness with DE/rand/1/bin (plus the refinement
    unless ``polish=False``).  ``population`` defaults to ``10 D``.
    ``params``: ``f_low``, ``f_high``, ``cr_low``, ``cr_high``."""
    size = default_population(model) if population is None else int(population)
    return solve_population("de", model, legs,
                            lambda problem, pop, fit, rng, term: DEPopulation(problem, pop, fit, rng, **params),
                            population=size, sample=initial_de_population,
                            rng=rng, init_range=init_range, center=center, spread=spread,
                            tolerance=tolerance, max_evals=max_evals, budget_s=budget_s, polish=polish, start=start)
