"""Real-coded genetic algorithm: the master population of GLPMA
(Chandra & Rolland 2014, section 3) and the GA of Chandra, Zhang & Rolland (2009).

Generational.  Each generation:

* **elitism** -- the best individual is copied unchanged;
* **roulette-wheel selection** of two parents with weights ``w_i = 1 / f_i``
  (floored at ``MIN_FITNESS``): the papers do not state their transform; the
  reciprocal keeps selection pressure while the fitness falls through twenty
  orders of magnitude (``1 / (1 + f)`` flattens to uniform selection below
  f ~ 1 and stalls the search there; BENCHMARKS.md, "Design measurements");
* **Wright's heuristic crossover** (Wright 1991) with probability
  ``crossover_rate``: ``child = better + u (better - worse)``, ``u ~ U(0, 1)``;
  otherwise the child is a copy of the first parent;
* **non-uniform mutation** (Michalewicz 1992) with probability
  ``mutation_rate`` per child: one random variable moves by
  ``+/- width (1 - v^((1 - t/T)^b))``, ``v ~ U(0, 1)``, where ``width`` is the
  initial range of that variable, ``t`` the generation and ``T`` the last
  generation the evaluation cap allows (004's "pivot" mutation is not
  specified, so this documented standard operator stands in for it).

Children identical to their parent are not re-evaluated and not counted.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..models.kernels import population_fitness
from ..runtime.compat import NUMBA_INLINE
from .driver import EvolutionaryState, solve_population

#: the papers' rates (Chandra & Rolland 2014; Chandra, Zhang & Rolland 2009)
CROSSOVER_RATE = 0.9
MUTATION_RATE = 0.1
#: floor of the fitness in the roulette weights 1 / f (an exact solution is not infinitely likely)
MIN_FITNESS = 1e-300
#: non-uniform mutation's shape parameter (Michalewicz 1992)
MUTATION_B = 5.0


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def roulette(cum, rng):
    """Roulette-wheel selection: the first index whose cumulative weight ``cum`` exceeds a uniform draw
    in [0, ``cum[-1]``), by bisection."""
    u = rng.random() * cum[-1]
    lo, hi = 0, cum.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cum[mid] < u:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def roulette_cumulative(fit, cum):
    """Cumulative roulette weights ``1 / f`` (floored at ``MIN_FITNESS``) into ``cum``."""
    s = 0.0
    for i in range(fit.shape[0]):
        s += 1.0 / max(fit[i], MIN_FITNESS)
        cum[i] = s


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def start_generation(pop, fit, cum, new, new_f, tolerance):
    """Elitism and roulette wheel of a new generation: the best individual into slot 0 of
    ``new`` and the cumulative weights into ``cum``.  False when the best is below ``tolerance``
    (converged: no new generation)."""
    best = np.argmin(fit)
    if fit[best] < tolerance:
        return False
    roulette_cumulative(fit, cum)
    new[0] = pop[best]
    new_f[0] = fit[best]
    return True


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def wright_crossover(pop, fit, a, b, rng, out):
    """Wright's heuristic crossover of ``pop[a]`` and ``pop[b]`` into ``out``:
    ``better + u (better - worse)``, ``u ~ U(0, 1)`` (one draw)."""
    better, worse = (a, b) if fit[a] <= fit[b] else (b, a)
    u = rng.random()
    out[:] = pop[better] + u * (pop[better] - pop[worse])


@njit(cache=True, error_model="numpy")
def rcga_generations(pop, fit, rng, n_generations, max_evals, tolerance, generation, last_generation,
                     crossover_rate, mutation_rate, mutation_b, width, kind, data, legs, n_res):
    """Evolve ``pop``/``fit`` in place; returns (generations, evaluations)."""
    N, n = pop.shape
    new = np.empty_like(pop)
    new_f = np.empty(N)
    changed = np.zeros(N, dtype=np.bool_)
    cum = np.empty(N)
    gens = 0
    evals = 0
    while gens < n_generations and evals + N - 1 <= max_evals:
        if not start_generation(pop, fit, cum, new, new_f, tolerance):
            break
        changed[0] = False
        t = min((generation + gens) / max(last_generation, 1.0), 1.0)
        for i in range(1, N):
            a = roulette(cum, rng)
            b = roulette(cum, rng)
            changed[i] = False
            if rng.random() < crossover_rate and a != b:
                wright_crossover(pop, fit, a, b, rng, new[i])
                changed[i] = True
            else:
                new[i] = pop[a]
                new_f[i] = fit[a]
            if rng.random() < mutation_rate:
                k = rng.integers(0, n)
                step = width[k] * (1.0 - rng.random() ** ((1.0 - t) ** mutation_b))
                new[i, k] += step if rng.random() < 0.5 else -step
                changed[i] = True
        m = 0
        for i in range(N):
            if changed[i]:
                m += 1
        if m > 0:
            idx = np.empty(m, dtype=np.int64)
            m = 0
            for i in range(N):
                if changed[i]:
                    idx[m] = i
                    m += 1
            f_new = population_fitness(new[idx], kind, data, legs, n_res)
            for q in range(m):
                new_f[idx[q]] = f_new[q]
            evals += m
        pop[:] = new
        fit[:] = new_f
        gens += 1
    return gens, evals


class RCGAPopulation(EvolutionaryState):
    name = "rcga"

    def __init__(self, problem, pop, fit, rng, *, width, max_evals, crossover_rate=CROSSOVER_RATE,
                 mutation_rate=MUTATION_RATE, mutation_b=MUTATION_B):
        super().__init__(problem, pop, fit, rng)
        self.width = np.ascontiguousarray(np.broadcast_to(np.asarray(width, dtype=float), (pop.shape[1],)))
        self.crossover_rate, self.mutation_rate = float(crossover_rate), float(mutation_rate)
        self.mutation_b = float(mutation_b)
        self.generation = 0
        self.last_generation = max(float(max_evals) / len(pop), 1.0)

    def advance(self, n_generations, max_evals, tolerance):
        p = self.problem
        gens, evals = rcga_generations(self.pop, self.fit, self.rng, n_generations, max_evals, tolerance,
                                       float(self.generation), self.last_generation, self.crossover_rate,
                                       self.mutation_rate, self.mutation_b, self.width,
                                       p.kind, p.data, p.legs, p.n_res)
        self.generation += gens
        return gens, evals


def mutation_width(init_range, spread, n_vars):
    """Per-variable width of the non-uniform mutation: the initial range, or
    six standard deviations of a warm-start spread."""
    if spread is not None:
        return np.broadcast_to(6.0 * np.asarray(spread, dtype=float), (n_vars,))
    low, high = init_range
    return np.broadcast_to(np.asarray(high, dtype=float) - np.asarray(low, dtype=float), (n_vars,))


def solve(model, legs, *, population=100, rng=None, init_range=(-50.0, 50.0), center=None, spread=None,
          tolerance=1e-20, max_evals=10_000, budget_s=None, start=None, polish=True, **params):
    """Minimise the model's fitness with the RCGA (plus the refinement unless
    ``polish=False``).  ``params``: ``crossover_rate``, ``mutation_rate``, ``mutation_b``."""
    return solve_population("rcga", model, legs, lambda problem, pop, fit, rng, term: RCGAPopulation(
        problem, pop, fit, rng, width=mutation_width(init_range, spread, model.n_vars), max_evals=max_evals, **params),
                            population=population, rng=rng, init_range=init_range, center=center, spread=spread,
                            tolerance=tolerance, max_evals=max_evals, budget_s=budget_s, polish=polish, start=start)
